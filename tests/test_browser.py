"""The workbench in a real browser: every notebook run in JupyterLab, its panels poked.

One JupyterLab server (from this environment) and one page of a headless system Chromium, where JupyterLab is
loaded once, serve the whole module; notebooks are opened there one after another, each with the
parameters of its checked FAST run (``FAST`` and ``CLASS``) injected as papermill injects them. Screenshots of
every panel go to ``test-output/browser/<notebook>/``. See ``tests/browser_support.py``.

This run is each notebook's one execution on the workbench's data in the session: it also stands for the
papermill run of ``tests/test_notebooks.py`` (the same checks on the saved notebook) and for the all-notebook
LocalCluster run of ``tests/test_reproduce_cluster.py``, which skip themselves where it runs.
"""

from __future__ import annotations

import sys
from pathlib import Path

import nbformat
import pytest

from tests.browser_support import (CHROMIUM, FAST_PARAMETERS, NOTEBOOK_DIR, OUTPUT_DIR, check_notebook,
                                   lab_session, prepare_notebook, project_notebooks, widget_manager_versions)

pytestmark = pytest.mark.browser

if not CHROMIUM.exists():
    pytest.skip(f"{CHROMIUM} not installed (apt-get install chromium); the browser test uses "
                "the system Chromium only", allow_module_level=True)
pytest.importorskip("playwright.sync_api", reason="playwright is not installed in this environment")

NOTEBOOKS = project_notebooks()


@pytest.fixture(scope="module")
def lab_root(tmp_path_factory) -> Path:
    """The server's root folder: prepared notebook copies are written here."""
    return tmp_path_factory.mktemp("lab-root")


@pytest.fixture(scope="module")
def cluster_address():
    """A LocalCluster the notebooks send their sweeps to (``DASK_SCHEDULER``), as ``reproduce --scheduler`` does:
    every notebook then runs once here for the browser and the cluster together."""
    distributed = pytest.importorskip("distributed", reason="dask.distributed is not installed")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None,
                                       scheduler_port=0, protocol="tcp")
    yield cluster.scheduler_address
    cluster.close()


@pytest.fixture(scope="module")
def lab(lab_root):
    """``(server, page)``, shared by the module and closed even when tests fail."""
    with lab_session(lab_root) as (server, page):
        yield server, page


def test_kernel_and_widget_manager_come_from_this_environment(lab):
    server, _ = lab
    spec = server.api("GET", "/api/kernelspecs")["kernelspecs"]["python3"]["spec"]
    assert Path(spec["argv"][0]).parent == Path(sys.executable).parent, (
        f"kernel 'python3' runs {spec['argv'][0]}, not this environment's {sys.executable}")
    served, installed = widget_manager_versions(server)
    assert served == installed, (f"JupyterLab serves widget manager {served}, but this environment's "
                                 f"jupyterlab_widgets ships {installed}")


@pytest.mark.parametrize(
    "notebook",
    NOTEBOOKS or [pytest.param(None, marks=pytest.mark.skip(reason=f"no notebooks in {NOTEBOOK_DIR} yet"))],
    ids=[p.stem for p in NOTEBOOKS] or ["no-notebooks"])
def test_notebook_in_jupyterlab(notebook, lab, lab_root, tmp_path, cluster_address):
    """Run every cell in the browser with the parameters of the checked FAST run (``FAST``, and ``CLASS`` where the
    notebook has it) and the sweeps on a LocalCluster, move a control of every panel; the notebook must join the
    cluster, and the saved run must pass the checks of ``tests/test_notebooks.py`` (summary, figure audit, class
    limits, whole tables: :func:`tests.test_notebooks.check_class_run`)."""
    from tests.test_notebooks import check_class_run, class_run_parameters
    from uwbwb import classroom

    server, page = lab
    summary = tmp_path / f"{notebook.stem}.summary.json"
    figures = tmp_path / f"{notebook.stem}.figures.json"
    parameters = {**class_run_parameters(notebook), "SUMMARY_PATH": str(summary),
                  "DASK_SCHEDULER": cluster_address}
    saved = prepare_notebook(notebook, lab_root, parameters, first_cell=classroom.hook_cell(figures))
    report = check_notebook(server, page, notebook.name, out_dir=OUTPUT_DIR / notebook.stem, save=True)
    assert report.panels, f"{notebook.name}: no panel was checked"
    assert f"Sweeps run on the Dask cluster at {cluster_address}" in report.output_text, \
        f"{notebook.name} did not join the cluster at {cluster_address}"
    check_class_run(notebook, parameters, summary, figures, nbformat.read(saved, as_version=4))


# --------------------------------------------------------------------------- self-check

_SETUP = "import matplotlib.pyplot as plt\nimport uwbwb as uw"
_PANEL = '''
def render(offset_m, n):
    {guard}
    fig, ax = plt.subplots(figsize=(4, 2.5))
    ax.plot(range(n), [{shown} + 0.1 * k for k in range(n)])
    ax.set_xlabel("k"); ax.set_ylabel("offset (m)")
    return fig, {{"offset (m)": {shown}, "points": n, "FAST": FAST}}

panel = uw.widgets.Panel("Self-check panel", {{
    "offset_m": uw.widgets.float_slider("offset", 0.5, 0.0, 1.0, 0.1, unit="m"),
    "n": uw.widgets.int_slider("points", 3, 2, 10),
}}, render)
panel
'''
#: name -> (code of the last cell, regex the harness's AssertionError must match, or None)
SELF_CHECKS = {
    "selfcheck_ok": (_PANEL.format(guard="", shown="offset_m"), None),
    "selfcheck_render_error": (
        _PANEL.format(guard="if offset_m > 0.55:\n        raise RuntimeError('offset above 0.55 m')",
                      shown="offset_m"),
        r"(?s)^selfcheck_render_error\.ipynb: panel 1: error after changing 'offset \(m\)'.*"
        r"Self-check panel.*RuntimeError: offset above 0\.55 m"),
    "selfcheck_cell_error": (_PANEL.format(guard="", shown="offset_m") + "\nundefined_name\n",
                             r"(?s)^selfcheck_cell_error\.ipynb: cell error .*NameError"),
    "selfcheck_stale_panel": (_PANEL.format(guard="", shown="0.5"),
                              r"(?s)^selfcheck_stale_panel\.ipynb: panel 1: changed 'offset \(m\)'.*"
                              r"neither the readout nor the figure updated"),
}


def _write_selfcheck_notebook(path: Path, code: str) -> None:
    params = nbformat.v4.new_code_cell("FAST = False\nSEED = 0")
    params.metadata["tags"] = ["parameters"]
    nb = nbformat.v4.new_notebook(cells=[
        nbformat.v4.new_markdown_cell("# Browser harness self-check"), params,
        nbformat.v4.new_code_cell(_SETUP), nbformat.v4.new_code_cell(code)])
    nbformat.write(nb, path)


@pytest.mark.parametrize("name", list(SELF_CHECKS))
def test_browser_selfcheck(name, lab, lab_root, tmp_path):
    """The harness passes a working notebook and fails broken ones, naming them."""
    server, page = lab
    code, failure = SELF_CHECKS[name]
    _write_selfcheck_notebook(tmp_path / f"{name}.ipynb", code)
    nb_path = prepare_notebook(tmp_path / f"{name}.ipynb", lab_root, FAST_PARAMETERS)
    injected = nbformat.read(nb_path, as_version=4).cells[2]
    assert injected.metadata.tags == ["injected-parameters"] and "FAST = True" in injected.source

    out_dir = OUTPUT_DIR / name
    if failure is None:
        report = check_notebook(server, page, nb_path.name, out_dir=out_dir)
        (change,) = report.panels
        assert change.readout_before != change.readout_after and change.figure_changed
        assert "FAST\tTrue" in change.readout_before  # the injected parameter was used
        assert all(p.stat().st_size > 0 for p in report.screenshots)
    else:
        with pytest.raises(AssertionError, match=failure) as caught:
            check_notebook(server, page, nb_path.name, out_dir=out_dir, update_timeout_s=5.0)
        assert str(caught.value).startswith(nb_path.name)
