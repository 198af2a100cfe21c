"""reproduce: executes notebooks with papermill, renders HTML, aggregates summaries."""

from __future__ import annotations

import json
import re
from pathlib import Path

import nbformat
import pytest

from uwbwb import cli
from uwbwb import notebook_params as nbp
from uwbwb import reproduce as rp
from uwbwb.metrics import Summary

PROJECT = Path(__file__).resolve().parents[1]

GOOD_PARAMS = 'FAST = False\nSEED = 0\nDATA_DIR = None\nSUMMARY_PATH = None\nN = 1\nLABEL = "default"\n'
GOOD_BODY = """\
import json
mode = "FAST" if FAST else "full"
rows = [
    {"notebook": "01_good", "quantity": "doubled N", "value": 2.5 * N, "unit": "m",
     "paper_value": None, "data": LABEL, "kind": "reproduced", "mode": mode},
    {"notebook": "01_good", "quantity": "fast | flag", "value": FAST, "unit": "",
     "paper_value": 1.0, "data": "synthetic", "kind": "target", "mode": mode},
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
        [{"notebook": "02_broken", "quantity": "old", "value": 1, "unit": "", "paper_value": None, "data": "",
          "kind": "reproduced", "mode": "FAST"}]))
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
    assert all(list(r) == list(Summary.COLUMNS) for r in rows)
    assert rows[0]["value"] == 10.0            # -p N 4 parsed as an int
    assert rows[0]["data"] == "synthetic run"  # -p LABEL ... kept as a string
    assert rows[1]["value"] is True            # --quick sets FAST=True
    assert json.loads((out / "01_good.summary.json").read_text()) == rows


@pytest.mark.notebook
def test_summary_markdown_has_numbers_and_status(ran):
    _, out = ran
    md = (out / "summary.md").read_text()
    assert "| 01_good | doubled N | 10 (FAST) | m |  | reproduced | FAST | synthetic run |" in md  # blank paper value
    assert r"| 01_good | fast \| flag | True (FAST) |  | 1 | target | FAST | synthetic |" in md
    head = md.split("## Headline numbers")[0]
    assert "**FAST mode.** Rows marked (FAST) come from FAST runs" in head
    status = {}
    for line in md.splitlines():
        cells = line.removeprefix("| ").removesuffix(" |").split(" | ")
        if len(cells) == 5 and cells[1] in ("ok", "failed"):
            status[cells[0]] = cells
    assert status["01_good"][1] == "ok" and status["01_good"][3] == "no" and status["01_good"][4] == ""
    assert float(status["01_good"][2]) > 0
    assert status["02_broken"][1] == "failed"
    assert status["02_broken"][4].startswith("RuntimeError: boom: deliberate failure")
    assert "1 of 2 notebooks ok." in md


@pytest.mark.notebook
def test_notebook_without_summary_counts_as_failed(tmp_path):
    _notebook(tmp_path / "03_silent.ipynb", GOOD_PARAMS, "x = 1 + 1")     # runs without publishing anything
    result = rp.reproduce(notebooks_dir=tmp_path, out=tmp_path / "out", timeout_s=120)
    (run,) = result.runs
    assert not run.ok and run.error.startswith("no summary file") and "03_silent.summary.json" in run.error
    assert result.exit_code == 1 and (tmp_path / "out" / "03_silent.html").exists()
    assert json.loads(result.summary_json.read_text()) == []
    assert "No notebook published a summary." in result.summary_md.read_text()


def test_a_value_typed_for_a_notebook_outside_the_table_takes_the_type_of_the_default():
    def parse(text, default):
        return nbp.infer(default).parse(text, "NAME")

    assert parse("8.20", "8.14") == "8.20"                   # a string default keeps the text as typed
    assert parse("None", "fast") == "None" and parse("", "x") == ""
    assert parse("True", False) is True and parse("false", True) is False
    assert parse("3", 1) == 3 and parse("3", 0.5) == 3.0 and isinstance(parse("3", 0.5), float)
    assert parse("1e-3", 0.5) == 0.001
    assert parse("(1, 2)", (1, 2, 3)) == (1, 2) and parse("1,", (1, 2)) == (1,)
    assert parse("('slow',)", ("slow", "fast")) == ("slow",)
    assert parse("3", None) == 3 and parse("[1, 2.5]", None) == [1, 2.5] and parse("t0", None) == "t0"
    assert parse("None", None) is None and parse("'07'", None) == "07"


@pytest.mark.parametrize("text, default, expected", [
    ("maybe", False, "True or False"),
    ("1", True, "True or False"),
    ("2.5", 1, "an integer"),
    ("True", 1, "an integer"),
    ("fast", 0.5, "a number"),
    ("None", 0.5, "a number"),
    ("1", (1, 2), "a tuple of values, each an integer"),
    ("slow,fast", ("slow", "fast"), "a tuple of distinct values, each text"),
    ("(1, 'x')", (1, 2), "a tuple"),
])
def test_a_typed_value_that_does_not_fit_the_default_is_refused(text, default, expected):
    with pytest.raises(ValueError, match=rf"-p NAME .*expected {re.escape(expected)}"):
        nbp.infer(default).parse(text, "NAME")


def test_resolve_parameters_checks_names_and_types_per_notebook(tmp_path):
    a = _notebook(tmp_path / "01_a.ipynb", GOOD_PARAMS + "TOURS = (1, 2, 3)\n", "")
    b = _notebook(tmp_path / "02_b.ipynb", GOOD_PARAMS + "TOURS = 'all'\n", "")
    resolved = rp.resolve_parameters([a, b], {"FAST": True}, text={"TOURS": "(2,)", "LABEL": "x"})
    assert resolved[a] == {"FAST": True, "TOURS": (2,), "LABEL": "x"}
    assert resolved[b] == {"FAST": True, "TOURS": "(2,)", "LABEL": "x"}   # typed by each notebook's default
    c = _notebook(tmp_path / "03_c.ipynb", "FAST = False\nSUMMARY_PATH = None\nONLY_HERE = 1\n", "")
    assert rp.resolve_parameters([a, c], text={"ONLY_HERE": "2"}) == {a: {}, c: {"ONLY_HERE": 2}}
    with pytest.raises(ValueError, match="unknown parameter.*NO_SUCH_PARAM.*valid names: DATA_DIR, FAST, LABEL"):
        rp.resolve_parameters([a, b], text={"NO_SUCH_PARAM": "1"})
    with pytest.raises(ValueError, match=r"01_a: -p FAST maybe: expected True or False \(the default of FAST is False\)"):
        rp.resolve_parameters([a], text={"FAST": "maybe"})
    with pytest.raises(ValueError, match="01_a: parameter N='4': expected an integer"):
        rp.resolve_parameters([a], {"N": "4"})
    with pytest.raises(ValueError, match="exactly one code cell tagged 'parameters', found 0"):
        nb = nbformat.v4.new_notebook()
        nbformat.write(nb, tmp_path / "04_none.ipynb")
        rp.resolve_parameters([tmp_path / "04_none.ipynb"], text={"N": "1"})


def test_the_readme_example_reaches_notebook_02_as_the_string_typed(monkeypatch, tmp_path):
    """``python -m uwbwb reproduce --only 02 -p STATIC_SESSION 8.20`` on the project's notebooks."""
    received = {}

    def fake_run(source, out_dir, parameters, **kwargs):   # stop before executing: record what would be passed
        received[source.stem] = dict(parameters)
        return rp.NotebookRun(notebook=source.stem, source=source, executed=out_dir / "x.ipynb", html=None,
                              summary=out_dir / "x.json", seconds=0.0, error=None)

    monkeypatch.setattr(rp, "run_notebook", fake_run)
    monkeypatch.chdir(PROJECT)                  # the default notebook folder is notebooks/ in the working directory
    argv = "reproduce --only 02 -p STATIC_SESSION 8.20".split() + ["--out", str(tmp_path)]
    assert cli.main(argv) == 0
    (stem,) = received
    assert stem.startswith("02") and received[stem] == {"STATIC_SESSION": "8.20"}
    assert rp.notebook_parameters(PROJECT / "notebooks" / f"{stem}.ipynb")["STATIC_SESSION"] == "8.14"


@pytest.mark.parametrize("argv, message", [
    (["-p", "FAST", "maybe"], "-p FAST maybe: expected True or False"),
    (["-p", "NO_SUCH_PARAM", "1"], "unknown parameter(s) NO_SUCH_PARAM"),
    (["-p", "N", "many"], "-p N many: expected an integer"),
    (["-p", "N", "1", "-p", "N", "2"], "-p N given twice"),
])
def test_cli_rejects_bad_parameters_before_any_notebook_runs(argv, message, monkeypatch, tmp_path, capsys):
    _notebook(tmp_path / "01_good.ipynb", GOOD_PARAMS, GOOD_BODY)
    monkeypatch.setattr(rp, "NOTEBOOKS_DIR", tmp_path)
    monkeypatch.setattr(rp, "run_notebook", lambda *a, **k: pytest.fail("a notebook ran"))
    assert cli.main(["reproduce", "--out", str(tmp_path / "out"), *argv]) == 2
    err = capsys.readouterr().err
    assert message in err
    if "unknown" in message:
        assert "valid names: DATA_DIR, FAST, LABEL, N, SEED" in err
    assert not (tmp_path / "out").exists()


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
    with pytest.raises(ValueError, match="unknown parameter"):
        rp.reproduce(notebooks_dir=tmp_path / "nb", out=tmp_path, parameters={"NOPE": 1})
    with pytest.raises(ValueError, match="expected True or False"):
        rp.reproduce(notebooks_dir=tmp_path / "nb", out=tmp_path, parameters={"FAST": "maybe"})
    _notebook(tmp_path / "nb" / "03_nofast.ipynb", "SUMMARY_PATH = None\n", "")
    with pytest.raises(ValueError, match="03_nofast does not declare"):
        rp.reproduce(notebooks_dir=tmp_path / "nb", out=tmp_path, quick=True)
    assert not (tmp_path / "summary.json").exists()


@pytest.mark.parametrize("content, problem", [
    (None, "no summary file"),
    ("{not json", "not valid JSON"),
    ("[]", "non-empty JSON list"),
    ('[{"notebook": "nb", "quantity": "q", "value": 1}]', "keys must be"),
    (json.dumps([dict.fromkeys(Summary.COLUMNS, "") | {"notebook": "other"}]), "names notebook 'other'"),
    (json.dumps([dict.fromkeys(Summary.COLUMNS, "") | {"notebook": "nb", "kind": "guess"}]), "kind must be"),
    (json.dumps([dict.fromkeys(Summary.COLUMNS, "") | {"notebook": "nb", "kind": "input", "mode": "quick"}]),
     "mode must be"),
    (json.dumps([dict.fromkeys(Summary.COLUMNS, "") | {"notebook": "nb", "kind": "input", "mode": "full"}]),
     "mode 'full', but the notebook ran with FAST=True"),
])
def test_read_summary_reports_problems(tmp_path, content, problem):
    path = tmp_path / "nb.summary.json"
    if content is not None:
        path.write_text(content)
    rows, error = rp.read_summary(path, "nb", "FAST")
    assert rows == [] and problem in error


def test_summary_markdown_formats_values():
    row = {"notebook": "nb", "quantity": "CEP95", "value": 0.123456789, "unit": "m", "paper_value": None,
           "data": "sim", "kind": "reproduced", "mode": "full"}
    fast = row | {"quantity": "CEP50", "paper_value": 0.1, "mode": "FAST", "kind": "target"}
    run = rp.NotebookRun(notebook="nb", source=Path("nb.ipynb"), executed=Path("nb.out.ipynb"), html=None,
                         summary=Path("nb.summary.json"), seconds=2.04, error=None, rows=(row,))
    md = rp.summary_markdown([run], {"FAST": False})
    assert "| nb | CEP95 | 0.1235 | m |  | reproduced | full | sim |" in md
    assert "FAST mode" not in md and "(FAST)" not in md
    assert "| nb | ok | 2.0 | no |  |" in md
    assert "`FAST=False`" in md and "All 1 notebooks ok." in md
    md = rp.summary_markdown([rp.NotebookRun(**{**run.__dict__, "rows": (row, fast)})])
    assert "| nb | CEP50 | 0.1235 (FAST) | m | 0.1 | target | FAST | sim |" in md
    assert md.index("**FAST mode.** Rows marked (FAST) come from FAST runs") < md.index("## Headline numbers")


def test_reproduce_says_which_notebooks_get_a_parameter_only_some_declare(tmp_path, monkeypatch):
    _notebook(tmp_path / "01_a.ipynb", GOOD_PARAMS, "")
    _notebook(tmp_path / "02_b.ipynb", "FAST = False\nSUMMARY_PATH = None\nTOURS = (1, 2)\n", "")
    received, lines = {}, []

    def fake_run(source, out_dir, parameters, **kwargs):
        received[source.stem] = dict(parameters)
        return rp.NotebookRun(notebook=source.stem, source=source, executed=out_dir / "x.ipynb", html=None,
                              summary=out_dir / "x.json", seconds=0.0, error=None)

    monkeypatch.setattr(rp, "run_notebook", fake_run)
    rp.reproduce(notebooks_dir=tmp_path, out=tmp_path / "out", quick=True, text_parameters={"TOURS": "(2,)"},
                 log=lines.append)
    assert received == {"01_a": {"FAST": True}, "02_b": {"FAST": True, "TOURS": (2,)}}
    assert "parameter TOURS goes to 02_b only (the others do not declare it)" in lines


def test_notebooks_start_longest_first_by_the_time_their_front_quotes(tmp_path, monkeypatch):
    """The run order follows each front's *Run time* for the mode (unknown first); the report keeps notebook order."""
    fronts = {"01_short": "[FAST](G.md#fast) 20 s, [full](G.md#full-mode) 1 min 3 s",
              "02_none": "",
              "03_long": "[FAST](G.md#fast) 10 s, [full](G.md#full-mode) 11 min",
              "04_mid": "[FAST](G.md#fast) 1 min 5 s, [full](G.md#full-mode) 4 min 41 s"}
    for stem, times in fronts.items():
        path = _notebook(tmp_path / f"{stem}.ipynb", GOOD_PARAMS, "")
        nb = nbformat.read(path, as_version=4)
        nb.cells[0].source = f"# {stem}\n\n**Run time** (measured): class mode 5 s, {times}." if times else "# x"
        nbformat.write(nb, path)
    started = []

    def fake_run(source, out_dir, parameters, **kwargs):
        started.append(source.stem)
        return rp.NotebookRun(notebook=source.stem, source=source, executed=out_dir / "x.ipynb", html=None,
                              summary=out_dir / "x.json", seconds=0.0, error=None)

    monkeypatch.setattr(rp, "run_notebook", fake_run)
    full = rp.reproduce(notebooks_dir=tmp_path, out=tmp_path / "full", jobs=1)
    assert started == ["02_none", "03_long", "04_mid", "01_short"]
    assert [r.notebook for r in full.runs] == list(fronts)
    started.clear()
    rp.reproduce(notebooks_dir=tmp_path, out=tmp_path / "fast", jobs=1, quick=True)
    assert started == ["02_none", "04_mid", "01_short", "03_long"]


def test_folders_are_arguments_with_defaults_in_the_working_directory_not_the_package(tmp_path, monkeypatch):
    """Installed as a wheel, the package holds no notebooks: the folders come from the caller."""
    (tmp_path / "notebooks").mkdir()
    _notebook(tmp_path / "notebooks" / "01_good.ipynb", GOOD_PARAMS, GOOD_BODY)
    monkeypatch.chdir(tmp_path)
    assert [p.name for p in rp.select_notebooks()] == ["01_good.ipynb"]
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    _notebook(elsewhere / "07_other.ipynb", GOOD_PARAMS, GOOD_BODY)
    assert [p.name for p in rp.select_notebooks(elsewhere)] == ["07_other.ipynb"]
    received = {}

    def fake_run(source, out_dir, parameters, **kwargs):
        received[source.name] = out_dir
        return rp.NotebookRun(notebook=source.stem, source=source, executed=out_dir / "x.ipynb", html=None,
                              summary=out_dir / "x.json", seconds=0.0, error=None)

    monkeypatch.setattr(rp, "run_notebook", fake_run)
    assert cli.main(["reproduce"], notebooks_dir=elsewhere, reports_dir=tmp_path / "mine") == 0
    assert received == {"07_other.ipynb": (tmp_path / "mine").resolve()}
    tooling = [*Path(rp.__file__).parent.glob("*.py"), Path(cli.__file__)]
    assert not [p.name for p in tooling if "__file__" in p.read_text(encoding="utf-8")]


READER_PARAMS = 'FAST = False\nDATA_DIR = None\nSUMMARY_PATH = None\nN = 1\n'
READER_BODY = """\
import json, os
from uwbwb.datasets.text import _read_bytes
size = len(_read_bytes(os.path.join(DATA_DIR, "ranges.txt")))
rows = [{"notebook": "01_reader", "quantity": "bytes read", "value": size * N, "unit": "", "paper_value": None,
         "data": "x", "kind": "reproduced", "mode": "FAST" if FAST else "full"}]
with open(SUMMARY_PATH, "w") as fh:
    json.dump(rows, fh)
"""


@pytest.mark.notebook
def test_a_second_run_reuses_a_notebook_only_while_nothing_it_depends_on_changed(tmp_path):
    notebooks, out, data = tmp_path / "notebooks", tmp_path / "reports", tmp_path / "data"
    notebooks.mkdir()
    data.mkdir()
    (data / "ranges.txt").write_text("1 2 3\n")
    source = _notebook(notebooks / "01_reader.ipynb", READER_PARAMS, READER_BODY)

    def run(**kw):
        params = {"DATA_DIR": str(data), **kw.pop("parameters", {})}
        (r,) = rp.reproduce(out=out, notebooks_dir=notebooks, parameters=params, timeout_s=120, **kw).runs
        assert r.ok, r.error
        return r

    first = run()
    assert not first.cached and first.rows[0]["value"] == 6
    stamp = first.executed.stat().st_mtime_ns
    again = run()
    assert again.cached and again.rows == first.rows and again.executed.stat().st_mtime_ns == stamp
    assert "| 01_reader | ok |" in (out / "summary.md").read_text() and "| yes |" in (out / "summary.md").read_text()
    (data / "ranges.txt").write_text("1 2 3 4\n")                    # the data file it read changed
    changed = run()
    assert not changed.cached and changed.rows[0]["value"] == 8
    assert run().cached
    assert not run(parameters={"N": 2}).cached                          # another parameter value
    assert not run(force=True).cached                                   # told to
    assert run().cached                                                 # the forced run's entry (N = 1) stands
    _notebook(source, READER_PARAMS, READER_BODY + "\n# an edit\n")   # the notebook changed
    assert not run().cached
    (out / "01_reader.html").unlink()                                   # an output is missing
    assert not run().cached


@pytest.mark.notebook
def test_notebooks_run_at_once_give_what_they_give_one_after_the_other(tmp_path):
    notebooks = tmp_path / "notebooks"
    notebooks.mkdir()
    for i in range(1, 3):
        body = GOOD_BODY.replace('"01_good"', f'"0{i}_good"').replace("2.5 * N", f"2.5 * N + {i}")
        _notebook(notebooks / f"0{i}_good.ipynb", GOOD_PARAMS, body)
    serial = rp.reproduce(out=tmp_path / "serial", notebooks_dir=notebooks, jobs=1, timeout_s=120)
    together = rp.reproduce(out=tmp_path / "together", notebooks_dir=notebooks, jobs=2, timeout_s=120)
    assert serial.ok and together.ok
    assert [r.notebook for r in together.runs] == ["01_good", "02_good"]    # notebook order
    assert together.rows == serial.rows
    assert json.loads(together.summary_json.read_text()) == json.loads(serial.summary_json.read_text())
    with pytest.raises(ValueError, match="jobs must be a whole number"):
        rp.reproduce(out=tmp_path / "x", notebooks_dir=notebooks, jobs=0)
