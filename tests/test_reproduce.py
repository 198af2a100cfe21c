"""reproduce: executes notebooks with papermill, renders HTML, aggregates summaries."""

from __future__ import annotations

import json
from pathlib import Path

import nbformat
import pytest

from uwbwb import cli
from uwbwb import reproduce as rp

GOOD_PARAMS = 'FAST = False\nSEED = 0\nDATA_DIR = None\nSUMMARY_PATH = None\nN = 1\nLABEL = "default"\n'
GOOD_BODY = """\
import json
rows = [
    {"notebook": "01_good", "quantity": "doubled N", "value": 2.5 * N, "unit": "m",
     "paper_value": None, "data": LABEL},
    {"notebook": "01_good", "quantity": "fast | flag", "value": FAST, "unit": "",
     "paper_value": 1.0, "data": "synthetic"},
]
with open(SUMMARY_PATH, "w") as fh:
    json.dump(rows, fh)
"""


def _notebook(path: Path, params: str, body: str) -> Path:
    nb = nbformat.v4.new_notebook()
    cell = nbformat.v4.new_code_cell(params)
    cell.metadata["tags"] = ["parameters"]
    nb.cells = [nbformat.v4.new_markdown_cell("# test notebook"), cell, nbformat.v4.new_code_cell(body)]
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nbformat.write(nb, path)
    return path


def _notebooks(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    _notebook(folder / "01_good.ipynb", GOOD_PARAMS, GOOD_BODY)
    _notebook(folder / "02_broken.ipynb", GOOD_PARAMS, 'raise RuntimeError("boom: deliberate failure")')
    return folder


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    """One CLI run over two notebooks: one good, one raising."""
    base = tmp_path_factory.mktemp("reproduce")
    notebooks, out = _notebooks(base / "notebooks"), base / "reports"
    out.mkdir()
    # A summary left from an earlier run must not count for this one.
    (out / "02_broken.summary.json").write_text(json.dumps(
        [{"notebook": "02_broken", "quantity": "old", "value": 1, "unit": "", "paper_value": None, "data": ""}]))
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rp, "NOTEBOOKS_DIR", notebooks)
        code = cli.main(["reproduce", "--quick", "--out", str(out), "-p", "N", "4",
                         "-p", "LABEL", "synthetic run", "--timeout", "120"])
    return code, out


@pytest.mark.notebook
def test_exit_code_is_non_zero_when_a_notebook_fails(ran):
    code, _ = ran
    assert code == 1


@pytest.mark.notebook
def test_executed_notebooks_and_html_are_written(ran):
    _, out = ran
    for stem in ("01_good", "02_broken"):
        assert nbformat.read(out / f"{stem}.ipynb", as_version=4).cells, stem
        assert "<html" in (out / f"{stem}.html").read_text()
    assert "boom: deliberate failure" in (out / "02_broken.html").read_text()
    assert not (out / "02_broken.summary.json").exists()  # the stale one was removed


@pytest.mark.notebook
def test_parameters_reach_the_notebook_and_summary_is_aggregated(ran):
    _, out = ran
    rows = json.loads((out / "summary.json").read_text())
    assert [r["quantity"] for r in rows] == ["doubled N", "fast | flag"]
    assert all(list(r) == list(rp.SUMMARY_KEYS) for r in rows)
    assert rows[0]["value"] == 10.0            # -p N 4 parsed as an int
    assert rows[0]["data"] == "synthetic run"  # -p LABEL ... kept as a string
    assert rows[1]["value"] is True            # --quick sets FAST=True
    assert json.loads((out / "01_good.summary.json").read_text()) == rows


@pytest.mark.notebook
def test_summary_markdown_has_numbers_and_status(ran):
    _, out = ran
    md = (out / "summary.md").read_text()
    assert "| 01_good | doubled N | 10 | m |  | synthetic run |" in md  # blank paper value
    assert r"| 01_good | fast \| flag | True |  | 1 | synthetic |" in md
    status = {}
    for line in md.splitlines():
        cells = line.removeprefix("| ").removesuffix(" |").split(" | ")
        if len(cells) == 4 and cells[1] in ("ok", "failed"):
            status[cells[0]] = cells
    assert status["01_good"][1] == "ok" and status["01_good"][3] == ""
    assert float(status["01_good"][2]) > 0
    assert status["02_broken"][1] == "failed"
    assert status["02_broken"][3].startswith("RuntimeError: boom: deliberate failure")
    assert "1 of 2 notebooks ok." in md


def test_notebook_without_summary_counts_as_failed(tmp_path, monkeypatch):
    import papermill

    def fake_execute(source, executed, **kwargs):  # "runs" without publishing anything
        nbformat.write(nbformat.read(source, as_version=4), executed)

    monkeypatch.setattr(papermill, "execute_notebook", fake_execute)
    _notebook(tmp_path / "03_silent.ipynb", GOOD_PARAMS, "x = 1 + 1")
    result = rp.reproduce(notebooks_dir=tmp_path, out=tmp_path / "out")
    (run,) = result.runs
    assert not run.ok and run.error.startswith("no summary file") and "03_silent.summary.json" in run.error
    assert result.exit_code == 1 and (tmp_path / "out" / "03_silent.html").exists()
    assert json.loads(result.summary_json.read_text()) == []
    assert "No notebook published a summary." in result.summary_md.read_text()


def test_parse_parameter_value():
    assert rp.parse_parameter_value("3") == 3
    assert rp.parse_parameter_value("0.25") == 0.25
    assert rp.parse_parameter_value("True") is True
    assert rp.parse_parameter_value("None") is None
    assert rp.parse_parameter_value("[1, 2.5]") == [1, 2.5]
    assert rp.parse_parameter_value("'07'") == "07"
    assert rp.parse_parameter_value("lias-planar-uwb") == "lias-planar-uwb"
    assert rp.parse_parameter_value("scenario1") == "scenario1"
    assert rp.parse_parameter_value("") == ""


def test_select_notebooks_by_prefix_or_stem(tmp_path):
    for stem in ("00_quickstart", "01_planar", "02_tdoa", "10_extra"):
        (tmp_path / f"{stem}.ipynb").write_text("{}")
    names = lambda paths: [p.stem for p in paths]  # noqa: E731
    assert names(rp.select_notebooks(tmp_path)) == ["00_quickstart", "01_planar", "02_tdoa", "10_extra"]
    assert names(rp.select_notebooks(tmp_path, ["02", "00_quickstart"])) == ["00_quickstart", "02_tdoa"]
    assert names(rp.select_notebooks(tmp_path, ["01_planar.ipynb"])) == ["01_planar"]
    assert names(rp.select_notebooks(tmp_path, ["1"])) == ["10_extra"]
    with pytest.raises(ValueError, match="no notebook matches '99'.*available: 00_quickstart"):
        rp.select_notebooks(tmp_path, ["00", "99"])
    with pytest.raises(ValueError, match="no notebooks"):
        rp.select_notebooks(tmp_path / "empty")


def test_reproduce_rejects_bad_settings_before_running(tmp_path):
    _notebooks(tmp_path / "nb")
    with pytest.raises(ValueError, match="SUMMARY_PATH"):
        rp.reproduce(notebooks_dir=tmp_path / "nb", out=tmp_path, parameters={"SUMMARY_PATH": "x"})
    with pytest.raises(ValueError, match="timeout"):
        rp.reproduce(notebooks_dir=tmp_path / "nb", out=tmp_path, timeout_s=0)
    assert not (tmp_path / "summary.json").exists()


@pytest.mark.parametrize("content, problem", [
    (None, "no summary file"),
    ("{not json", "not valid JSON"),
    ("[]", "non-empty JSON list"),
    ('[{"notebook": "nb", "quantity": "q", "value": 1}]', "keys must be"),
    (json.dumps([dict.fromkeys(rp.SUMMARY_KEYS, "") | {"notebook": "other"}]), "names notebook 'other'"),
])
def test_read_summary_reports_problems(tmp_path, content, problem):
    path = tmp_path / "nb.summary.json"
    if content is not None:
        path.write_text(content)
    rows, error = rp.read_summary(path, "nb")
    assert rows == [] and problem in error


def test_summary_markdown_formats_values():
    row = {"notebook": "nb", "quantity": "CEP95", "value": 0.123456789, "unit": "m", "paper_value": None,
           "data": "sim"}
    run = rp.NotebookRun(notebook="nb", source=Path("nb.ipynb"), executed=Path("nb.out.ipynb"), html=None,
                         summary=Path("nb.summary.json"), seconds=2.04, error=None, rows=(row,))
    md = rp.summary_markdown([run], {"FAST": True})
    assert "| nb | CEP95 | 0.1235 | m |  | sim |" in md
    assert "| nb | ok | 2.0 |  |" in md
    assert "`FAST=True`" in md and "All 1 notebooks ok." in md
