"""reproduce --scheduler: notebooks as tasks on a Dask cluster, each receiving the cluster as DASK_SCHEDULER."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.test_reproduce import _notebook as notebook
from uwbwb import cli
from uwbwb import reproduce as rp

distributed = pytest.importorskip("distributed", reason="dask.distributed is not installed (pip install 'uwbwb[dask]')")

NOTEBOOK_DIR = Path(__file__).resolve().parents[1] / "notebooks"
PARAMS = 'FAST = False\nSEED = 0\nDATA_DIR = None\nSUMMARY_PATH = None\nDASK_SCHEDULER = None\n'
BODY = """\
import json
from uwbwb import parallel
def square(x):
    return x * x
tasks = [parallel.Task({"x": x}) for x in range(6)]
total = sum(r for _, r in parallel.imap(square, tasks, scheduler=DASK_SCHEDULER, progress=False))
rows = [{"notebook": NAME, "quantity": "sum of squares", "value": total, "unit": "", "paper_value": None,
         "data": str(DASK_SCHEDULER), "kind": "reproduced", "mode": "FAST" if FAST else "full"}]
with open(SUMMARY_PATH, "w") as fh:
    json.dump(rows, fh)
"""


def _notebook(path: Path, params: str, body: str) -> Path:
    return notebook(path, params, f"NAME = {path.stem!r}\n" + body)


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None,
                                       scheduler_port=0, protocol="tcp")
    c = distributed.Client(cluster, set_as_default=False)
    yield c
    c.close()
    cluster.close()


@pytest.mark.notebook
def test_notebooks_run_as_tasks_and_send_their_sweeps_to_the_same_cluster(tmp_path, client):
    folder = tmp_path / "notebooks"
    folder.mkdir()
    for stem in ("01_a", "02_b", "03_c"):
        _notebook(folder / f"{stem}.ipynb", PARAMS, BODY)
    _notebook(folder / "04_broken.ipynb", PARAMS, 'raise RuntimeError("deliberate")')
    lines = []
    result = rp.reproduce(notebooks_dir=folder, out=tmp_path / "out", quick=True, scheduler=client, timeout_s=120,
                          log=lines.append)
    assert [r.notebook for r in result.runs] == ["01_a", "02_b", "03_c", "04_broken"]
    assert [r.ok for r in result.runs] == [True, True, True, False], [r.error for r in result.runs]
    assert result.runs[3].error.startswith("RuntimeError: deliberate")
    rows = json.loads(result.summary_json.read_text())
    assert [r["value"] for r in rows] == [55, 55, 55]
    assert {r["data"] for r in rows} == {client.scheduler.address}       # each notebook got the cluster
    assert all((tmp_path / "out" / f"{s}.html").is_file() for s in ("01_a", "04_broken"))
    assert "DASK_SCHEDULER" in result.summary_md.read_text()
    assert any("on the Dask cluster" in line for line in lines)


def test_scheduler_needs_the_parameter_in_every_notebook_and_only_once(tmp_path, client):
    folder = tmp_path / "notebooks"
    folder.mkdir()
    _notebook(folder / "01_a.ipynb", PARAMS, BODY)
    _notebook(folder / "02_old.ipynb", PARAMS.replace("DASK_SCHEDULER = None\n", ""), BODY)
    with pytest.raises(ValueError, match="02_old does not declare"):
        rp.reproduce(notebooks_dir=folder, out=tmp_path / "out", scheduler=client)
    with pytest.raises(ValueError, match="give the cluster once"):
        rp.reproduce(notebooks_dir=folder, only=["01"], out=tmp_path / "out", scheduler=client,
                     text_parameters={"DASK_SCHEDULER": "local"})


def test_cli_reproduce_quick_runs_the_notebooks_on_a_local_cluster(tmp_path, capsys):
    """`reproduce --scheduler local --quick` from the command line: the notebooks of a folder, concurrently, on one
    LocalCluster that each notebook's sweeps join. (The workbench's own notebooks join a cluster in
    ``tests/test_browser.py``, which runs each of them once with ``DASK_SCHEDULER`` set; without a browser, the
    next test runs them here.)"""
    folder = tmp_path / "notebooks"
    folder.mkdir()
    for stem in ("01_a", "02_b"):
        _notebook(folder / f"{stem}.ipynb", PARAMS, "from uwbwb import parallel\nprint(parallel.describe(DASK_SCHEDULER))\n"
                  + BODY)
    out = tmp_path / "reports"
    code = cli.main(["reproduce", "--scheduler", "local", "--quick", "--out", str(out), "--timeout", "300"],
                    notebooks_dir=folder)
    printed = capsys.readouterr().out
    assert code == 0, printed
    assert "Sweeps run on the Dask cluster at tcp://" in printed and "dashboard" in printed
    for stem in ("01_a", "02_b"):
        assert "Sweeps run on the Dask cluster at tcp://" in (out / f"{stem}.ipynb").read_text(), stem
    rows = json.loads((out / "summary.json").read_text())
    assert [r["value"] for r in rows] == [55, 55] and {r["mode"] for r in rows} == {"FAST"}
    assert len({r["data"] for r in rows}) == 1 and rows[0]["data"].startswith("tcp://")   # both on one cluster
    assert "DASK_SCHEDULER='tcp://" in (out / "summary.md").read_text()


@pytest.mark.notebook
def test_cli_reproduce_quick_runs_every_notebook_on_a_local_cluster(tmp_path, capsys, request):
    """Without the browser test: every notebook of the workbench, concurrently, on one LocalCluster."""
    from tests.browser_support import browser_runs

    stems = sorted(p.stem for p in NOTEBOOK_DIR.glob("*.ipynb"))
    if set(stems) <= browser_runs(request.config):
        pytest.skip("tests/test_browser.py runs every notebook on a LocalCluster in this session")
    out = tmp_path / "reports"
    code = cli.main(["reproduce", "--scheduler", "local", "--quick", "--out", str(out), "--timeout", "900"])
    printed = capsys.readouterr().out
    assert code == 0, printed
    for stem in stems:
        assert "Sweeps run on the Dask cluster at tcp://" in (out / f"{stem}.ipynb").read_text(), \
            f"{stem} did not join the cluster"
    rows = json.loads((out / "summary.json").read_text())
    assert {r["notebook"] for r in rows} == set(stems) and {r["mode"] for r in rows} == {"FAST"}
