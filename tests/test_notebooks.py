"""Every notebook runs end to end (FAST and class mode) and is committed clean; the executed notebook
passes the figure audit and the class limits of :mod:`uwbwb.classroom`."""

from __future__ import annotations

import json
from pathlib import Path

import nbformat
import pytest

from tests.browser_support import SMALLEST
from uwbwb.reproduce import read_summary

NOTEBOOK_DIR = Path(__file__).resolve().parents[1] / "notebooks"
NOTEBOOKS = sorted(NOTEBOOK_DIR.glob("*.ipynb"))
#: Hard limit per notebook in FAST mode (seconds of kernel time per cell).
CELL_TIMEOUT_S = 600
#: Notebooks whose figure audit, class limits and code rules (:mod:`uwbwb.classroom`) are enforced (the
#: audits run on every notebook and their findings are reported as warnings for the others). Add a
#: notebook's stem here once it has ``CLASS = False`` in its parameters cell, its research cells tagged
#: and the audits pass.
AUDITED = ("00_quickstart", "01_set_noise_pf", "02_pruning_nls", "03_ekf_motion_models", "04_doppler_beacons",
           "05_uwb_ins_fusion", "06_scoreboard")


def _ids(paths):
    return [p.stem for p in paths]


def test_there_are_notebooks():
    assert NOTEBOOKS, f"no notebooks found in {NOTEBOOK_DIR}"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=_ids(NOTEBOOKS))
def test_notebook_committed_clean(path):
    nb = nbformat.read(path, as_version=4)
    dirty = [i for i, c in enumerate(nb.cells)
             if c.cell_type == "code" and (c.get("outputs") or c.get("execution_count") is not None)]
    assert not dirty, f"{path.name}: code cells {dirty} carry outputs or execution counts"
    assert "widgets" not in nb.metadata, f"{path.name}: widget state saved in metadata"
    tagged = [i for i, c in enumerate(nb.cells) if "parameters" in c.get("metadata", {}).get("tags", [])]
    assert len(tagged) == 1, f"{path.name}: needs exactly one cell tagged 'parameters', has {len(tagged)}"
    # parse the cell the way papermill does: a line it cannot read is a parameter it cannot set
    from papermill.translators import PythonTranslator

    cell = nb.cells[tagged[0]]
    names = {p.name for p in PythonTranslator.inspect(cell)}
    assignments = [ln for ln in cell.source.splitlines() if "=" in ln and not ln.lstrip().startswith("#")]
    assert len(names) == len(assignments), \
        f"{path.name}: papermill reads {sorted(names)} from {len(assignments)} assignment lines (no '=' in comments)"
    for name in ("FAST", "SEED", "DATA_DIR", "SUMMARY_PATH", "DASK_SCHEDULER"):
        assert name in names, f"{path.name}: parameters cell lacks {name}"
    assert nb.cells[0].cell_type == "markdown", f"{path.name}: first cell must be the citation/overview"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=_ids(NOTEBOOKS))
def test_notebook_code_rules(path):
    """Code cells of at most 20 lines and no ``def`` outside the final widget cell, no private names
    (enforced for :data:`AUDITED`, a warning for the others)."""
    import warnings

    from uwbwb.classroom import code_rules

    problems = code_rules(nbformat.read(path, as_version=4))
    if path.stem in AUDITED:
        assert not problems, f"{path.name}: " + "; ".join(problems)
    elif problems:
        warnings.warn(f"not yet audited ({path.stem} is not in AUDITED): " + "; ".join(problems), stacklevel=1)


def class_run_parameters(path: Path) -> dict:
    """The parameters of a notebook's checked FAST run: ``FAST``, and ``CLASS`` where the notebook has it."""
    from uwbwb.reproduce import notebook_parameters

    return {"FAST": True, **({"CLASS": True} if "CLASS" in notebook_parameters(path) else {})}


def check_class_run(path: Path, parameters: dict, summary: Path, figures: Path, executed) -> None:
    """What a notebook's FAST run (``parameters`` from :func:`class_run_parameters`) must give: a summary,
    and the figure audit, class limits and whole tables of :mod:`uwbwb.classroom` on the ``executed``
    notebook and the figures the hook cell recorded into ``figures`` (enforced for the stems in
    :data:`AUDITED`, reported as warnings for the others). Used here and by ``tests/test_browser.py``."""
    import warnings

    from uwbwb import classroom

    rows, problem = read_summary(summary, path.stem, "FAST")   # keys, kind, and every row marked FAST
    assert problem is None and rows, f"{path.name}: {problem or 'no summary rows'}"
    found = {"figure audit": classroom.figure_audit(json.loads(figures.read_text()), executed),
             "class limits": classroom.class_limits(executed), "cut tables": classroom.cut_tables(executed)}
    report = "; ".join(f"{path.name} {what}: " + "; ".join(p) for what, p in found.items() if p)
    if path.stem in AUDITED:
        assert "CLASS" in parameters, f"{path.name}: audited notebooks need CLASS in their parameters cell"
        assert not report, report
    elif report:
        warnings.warn(f"not yet audited ({path.stem} is not in AUDITED): {report}", stacklevel=1)


@pytest.mark.notebook
@pytest.mark.parametrize("path", NOTEBOOKS, ids=_ids(NOTEBOOKS))
def test_notebook_executes_fast(path, tmp_path, request):
    """Execute with papermill in FAST mode, and in class mode where the notebook has ``CLASS``; any
    error fails, a summary must be written, and the figure audit and class limits must hold
    (:func:`check_class_run`). Where the browser test runs the notebook in this session, that run
    (the same parameters, in JupyterLab) is checked the same way and this one is skipped."""
    import papermill as pm

    from tests.browser_support import browser_runs
    from uwbwb import classroom

    if path.stem in browser_runs(request.config):
        pytest.skip("tests/test_browser.py runs this notebook with these parameters and checks that run")
    summary = tmp_path / f"{path.stem}.summary.json"
    figures = tmp_path / f"{path.stem}.figures.json"
    prepared, out = tmp_path / "prepared" / path.name, tmp_path / path.name
    prepared.parent.mkdir()
    nb = nbformat.read(path, as_version=4)
    nb.cells.insert(0, classroom.hook_cell(figures))     # records every Axes while the notebook runs
    nbformat.write(nb, prepared)
    parameters = {**class_run_parameters(path), "SUMMARY_PATH": str(summary)}
    try:
        pm.execute_notebook(str(prepared), str(out), parameters=parameters,
                            kernel_name="python3", cwd=str(NOTEBOOK_DIR), progress_bar=False,
                            execution_timeout=CELL_TIMEOUT_S)
    except pm.PapermillExecutionError as exc:
        pytest.fail(f"{path.name} failed in cell {exc.exec_count}: {exc.ename}: {exc.evalue}")
    check_class_run(path, parameters, summary, figures, nbformat.read(out, as_version=4))


#: Notebooks whose ``CLASS = False`` cells no test on generated recordings executes (04 has no real-data section,
#: 05's needs an i-ASL flight): where the browser test runs them in class mode, they also run here in FAST alone.
RESEARCH_ONLY_HERE = ("04_doppler_beacons", "05_uwb_ins_fusion")


@pytest.mark.notebook
@pytest.mark.parametrize("stem", RESEARCH_ONLY_HERE)
def test_research_cells_run_fast(stem, tmp_path, request):
    """FAST with ``CLASS = False`` on the datasets found (as ``reproduce --quick`` runs it, at the sizes of
    ``SMALLEST``): no error, a FAST summary, no cut table. Without the browser test the all-notebook LocalCluster
    reproduce test runs these cells."""
    import papermill as pm

    from tests.browser_support import browser_runs
    from uwbwb import classroom

    if stem not in browser_runs(request.config):
        pytest.skip("the browser test does not run this notebook here: its research cells run in the LocalCluster "
                    "reproduce test (tests/test_reproduce_cluster.py)")
    summary, out = tmp_path / "summary.json", tmp_path / f"{stem}.ipynb"
    try:
        pm.execute_notebook(str(NOTEBOOK_DIR / f"{stem}.ipynb"), str(out),
                            parameters={"FAST": True, **SMALLEST[stem], "SUMMARY_PATH": str(summary)},
                            kernel_name="python3", cwd=str(NOTEBOOK_DIR), progress_bar=False,
                            execution_timeout=CELL_TIMEOUT_S)
    except pm.PapermillExecutionError as exc:
        pytest.fail(f"{stem} failed in cell {exc.exec_count}: {exc.ename}: {exc.evalue}")
    rows, problem = read_summary(summary, stem, "FAST")
    assert problem is None and rows, f"{stem}: {problem or 'no summary rows'}"
    cut = classroom.cut_tables(nbformat.read(out, as_version=4))
    assert not cut, f"{stem}: " + "; ".join(cut)


def _run_on(notebook: str, tmp_path, data_dir, **parameters) -> list[dict]:
    """Execute ``notebook`` in FAST mode on the data tree ``data_dir``; return its published summary rows."""
    import papermill as pm

    summary = tmp_path / "summary.json"
    pm.execute_notebook(str(NOTEBOOK_DIR / notebook), str(tmp_path / "out.ipynb"),
                        parameters={"FAST": True, "DATA_DIR": str(data_dir), "SUMMARY_PATH": str(summary),
                                    **parameters},
                        kernel_name="python3", cwd=str(NOTEBOOK_DIR), progress_bar=False,
                        execution_timeout=CELL_TIMEOUT_S)
    from uwbwb import classroom

    cut = classroom.cut_tables(nbformat.read(tmp_path / "out.ipynb", as_version=4))
    assert not cut, f"{notebook}: " + "; ".join(cut)
    return json.loads(summary.read_text())


@pytest.mark.notebook
def test_quickstart_runs_unchanged_on_another_lias_recording(tmp_path):
    """A recording that is not in ../shared (synthetic, upstream layout, run name 'medium')."""
    import numpy as np

    from tests.fixtures import lias as fx

    data_dir = tmp_path / "data"
    rng = np.random.default_rng(11)
    fx.make_tree(data_dir, rng=rng, dynamic={"medium": {"duration_s": 20.0, "clock_offset_s": 0.2}},
                 sessions=[fx.session_814(rng)])
    rows = _run_on("00_quickstart.ipynb", tmp_path, data_dir, RECORDING="medium")
    assert {r["data"] for r in rows} == {"lias-planar-uwb/medium"}


@pytest.mark.notebook
def test_set_noise_runs_unchanged_on_another_lias_recording(tmp_path):
    """Notebook 01's real-data section on a recording that is not in ../shared (run name 'medium')."""
    import numpy as np

    from tests.fixtures import lias as fx

    data_dir = tmp_path / "data"
    rng = np.random.default_rng(12)
    fx.make_tree(data_dir, rng=rng, dynamic={"medium": {"duration_s": 30.0, "clock_offset_s": 0.3}},
                 sessions=[fx.session_814(rng)])
    rows = _run_on("01_set_noise_pf.ipynb", tmp_path, data_dir, RECORDING="medium")
    real = [r for r in rows if r["data"] != "synthetic"]
    assert real and {r["data"] for r in real} == {"lias-planar-uwb/medium"}
    assert {r["mode"] for r in rows} == {"FAST"}
    kinds = {r["quantity"]: r["kind"] for r in rows}
    assert all(k == "target" for q, k in kinds.items() if q.startswith(("raw error, recording", "top")))
    assert all(k == "input" for q, k in kinds.items() if q.startswith("fixes"))


@pytest.mark.notebook
def test_pruning_runs_unchanged_on_other_recordings(tmp_path):
    """Notebook 02 on recordings that are not in ../shared: another LIAS run, and a Hanyang tree of short static files
    with a dynamic case that is not an upstream name (chosen by HANYANG_CASE) for its Hanyang section."""
    import numpy as np

    from tests.fixtures import hanyang as hfx
    from tests.fixtures import lias as fx
    from uwbwb.experiments.hanyang.sections import EXTERNAL

    data_dir = tmp_path / "data"
    rng = np.random.default_rng(12)
    fx.make_tree(data_dir, rng=rng, dynamic={"medium": {"duration_s": 40.0, "clock_offset_s": 0.2}},
                 sessions=[fx.session_814(rng, files=((1, 0), (2, 0), (3, 0), (1, 60)))], static_rows=300)
    hfx.write_dataset(data_dir / "hanyang-outdoor-uwb", rng=rng, distances_m=(2, 4, 10, 20))   # 12 samples a file
    case = hfx.write_dynamic_tree(data_dir / "hanyang-outdoor-uwb", rng=rng, speed_mps=4.0)[3].name
    rows = _run_on("02_pruning_nls.ipynb", tmp_path, data_dir, RECORDING="medium", HANYANG_CASE=case)
    data = {r["data"] for r in rows}
    assert {"synthetic", "lias-planar-uwb/8.14", "lias-planar-uwb/medium"} <= data
    assert "hanyang-outdoor-uwb/static" not in data                   # no file long enough: no rows, no KeyError
    assert {r["mode"] for r in rows} == {"FAST"}
    assert {r["kind"] for r in rows if not r["data"].endswith(EXTERNAL)} == {"reproduced"}
    assert {r["kind"] for r in rows if r["data"].endswith(EXTERNAL)} == {"input"}     # the authors' estimates
    hy = [r for r in rows if r["data"] == f"hanyang-outdoor-uwb/{case}"]
    assert any(r["quantity"].startswith("RMSE_2d ratio NLS residual pruning / NLS (epochs both covered") for r in hy)


@pytest.mark.notebook
def test_motion_models_runs_unchanged_on_other_recordings(tmp_path):
    """Notebook 03 on recordings that are not in ../shared: a LIAS run 'medium', the IASL fixture scenarios and a
    Hanyang dynamic tree whose case (chosen by HANYANG_CASE) is not an upstream name.

    Its checks must hold for any recording of these formats; the real-data rows must come from these files.
    """
    import numpy as np

    from tests.fixtures import hanyang as hfx
    from tests.fixtures import iasl as fx_iasl
    from tests.fixtures import lias as fx_lias

    data_dir = tmp_path / "data"
    rng = np.random.default_rng(23)
    fx_lias.make_tree(data_dir, rng=rng, dynamic={"medium": {"duration_s": 30.0, "clock_offset_s": 0.2}},
                      sessions=[fx_lias.session_814(rng)])
    fx_iasl.write_dataset(data_dir / "iasl-uwb-imu", rng=rng, duration_s=30.0)
    hfx.write_dataset(data_dir / "hanyang-outdoor-uwb", rng=rng, distances_m=(2, 4, 10, 20))
    case = hfx.write_dynamic_tree(data_dir / "hanyang-outdoor-uwb", rng=rng, speed_mps=4.0)[1].name
    rows = _run_on("03_ekf_motion_models.ipynb", tmp_path, data_dir, RECORDING="medium", HANYANG_CASE=case,
                   **SMALLEST["03_ekf_motion_models"])
    assert {r["data"] for r in rows} == {"synthetic", "lias-planar-uwb/medium", "iasl-uwb-imu/scenario2",
                                         f"hanyang-outdoor-uwb/{case}"}
    assert any(r["quantity"].startswith("RMSE_2d ratio EKF-RW ranges / raw LS (epochs both covered") for r in rows
               if r["data"] == f"hanyang-outdoor-uwb/{case}")
    assert {r["mode"] for r in rows} == {"FAST"} and {r["kind"] for r in rows} == {"reproduced", "target"}
    real = [r for r in rows if r["data"] != "synthetic"]
    assert real and all(r["kind"] == "reproduced" and r["paper_value"] is None for r in real)


@pytest.mark.notebook
def test_scoreboard_runs_unchanged_on_another_lias_recording(tmp_path):
    """Notebook 06 on generated trees: a LIAS run 'medium' (biased ranges) and a Hanyang dynamic tree
    whose case names differ from upstream's: the boards and their checks hold for any recording of
    these formats, and the Hanyang rows come from the case chosen by parameter."""
    import numpy as np

    from tests.fixtures import hanyang as hfx
    from tests.fixtures import lias as fx

    data_dir = tmp_path / "data"
    rng = np.random.default_rng(12)
    fx.make_tree(data_dir, rng=rng, dynamic={"medium": {"duration_s": 30.0, "clock_offset_s": 0.3}},
                 sessions=[fx.session_814(rng)])
    cases = hfx.write_dynamic_tree(data_dir / "hanyang-outdoor-uwb", rng=rng, speed_mps=4.0)
    chosen = cases[-1].name
    rows = _run_on("06_scoreboard.ipynb", tmp_path, data_dir, LIAS_RECORDING="medium", HANYANG_CASES=[chosen],
                   **SMALLEST["06_scoreboard"])
    ours = f"hanyang-outdoor-uwb/{chosen}"
    assert {r["data"] for r in rows} == {"synthetic", "lias-planar-uwb/medium", ours,
                                         f"{ours} (external: authors' estimates)",
                                         "hanyang-outdoor-uwb/1 cases"}          # the declared method's mean row
    assert {r["mode"] for r in rows} == {"FAST"}
    assert {r["kind"] for r in rows if not r["data"].startswith("hanyang")} == {"reproduced"}
    assert {r["kind"] for r in rows if "(external" in r["data"]} == {"input"}
    assert any(r["quantity"] == "RMSE/own bound, EKF-RF" for r in rows)
    assert any(r["quantity"].startswith("authors LS RMSE_2d, recomputed") for r in rows
               if r["data"].startswith(ours))
