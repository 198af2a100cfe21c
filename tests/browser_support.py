"""Drive JupyterLab in headless Chromium: run a notebook, then check and poke its panels.

Used by ``tests/test_browser.py`` and ``benchmarks/bench_widgets.py``.

* :func:`prepare_notebook` writes a copy of a notebook with parameters injected
  the way papermill injects them (same functions, same "injected-parameters"
  cell after the cell tagged ``parameters``), outputs cleared, kernel ``python3``.
* :class:`LabServer` runs ``jupyter lab`` from this interpreter's environment on
  127.0.0.1 with a random port and token and throw-away runtime, config,
  settings and workspace folders; it shuts down with its kernels, whatever happens.
* :func:`launch_chromium` starts the system Chromium (never a downloaded one).
* :func:`lab_session` loads JupyterLab once into one page; every notebook is
  opened in that page as a tab and closed (its kernel shut down) when checked.
* :func:`check_notebook` opens a notebook, runs all cells, asserts that nothing
  failed, changes one control of every ``uwbwb-panel`` and asserts that the
  panel updated; every failure is an ``AssertionError`` naming the notebook.
  With ``save=True`` JupyterLab saves the executed notebook (before any control
  moves), so that the one run also serves the checks of an executed notebook.

JupyterLab is told to expose its application object (``window.jupyterapp``,
the setting JupyterLab's own UI tests use), so cells are run with the
``notebook:run-all-cells`` command and progress is read from the notebook model
rather than from pixels.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK_DIR = ROOT / "notebooks"
OUTPUT_DIR = ROOT / "test-output" / "browser"
CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]
#: Parameters the browser test injects (the same as CI's papermill runs).
FAST_PARAMETERS = {"FAST": True}
#: Sizes below FAST for the runs whose point is a path, not a number (the runs on generated recordings, the FAST
#: runs of 04's and 05's ``CLASS = False`` cells): the smallest that still run every section and panel. Notebooks not
#: named run at FAST sizes. 04 takes its class-mode draws and PF runs (``StudyConfig.for_class``); 05 and 06 score
#: at a lower epoch rate, 05 on a shorter static run, 06 over fewer Monte Carlo runs (3.5 Hz still gives a tag the
#: 40 scored epochs the board needs on the 15 s second half of a 30 s generated recording; 2.5 Hz does not).
SMALLEST = {"03_ekf_motion_models": {"SIM_DURATION_S": 40.0, "GRID_POINTS": 3},
            "04_doppler_beacons": {"N_BRUTE": 5_000_000, "N_POSITIONS": 30_000, "PF_RUNS": 4},
            "05_uwb_ins_fusion": {"RATE_HZ": 2.0, "STATIC_S": 10.0},
            "06_scoreboard": {"RATE_HZ": 3.5, "MC_RUNS": 5}}
#: Longest time one notebook may take to run all its cells.
RUN_TIMEOUT_S = float(os.environ.get("UWBWB_BROWSER_TIMEOUT_S", "600"))
#: Longest time JupyterLab may take to open a notebook and start its kernel.
OPEN_TIMEOUT_S = 180.0
#: Longest time a panel may take to update after a control change.
UPDATE_TIMEOUT_S = 60.0
#: A panel counts as updated once its output has not changed for this long.
SETTLE_S = 0.3
#: Longest time widget views may show "Loading widget..." after the last cell ran.
WIDGET_LOAD_TIMEOUT_S = 30.0

# JupyterLab user settings for the throw-away settings folder: every cell attached to the
# DOM (the default windowing skips off-screen cells), no news or update checks.
LAB_SETTINGS = {
    "@jupyterlab/notebook-extension/tracker.jupyterlab-settings": {"windowingMode": "none"},
    "@jupyterlab/apputils-extension/notification.jupyterlab-settings":
        {"fetchNews": "false", "checkForUpdates": False},
}


def project_notebooks() -> list[Path]:
    """The project's notebooks, sorted by name."""
    return sorted(NOTEBOOK_DIR.glob("*.ipynb"))


#: Node-id prefix of the browser test's run of one project notebook (``...[<stem>]``).
BROWSER_RUN = "tests/test_browser.py::test_notebook_in_jupyterlab["


def browser_runs(config) -> set[str]:
    """Stems of the notebooks the browser test runs in this pytest session (selected, not deselected, and
    collected: the module skips itself without Chromium or Playwright); set by ``tests/conftest.py``."""
    return getattr(config, "uwbwb_browser_runs", set())


# --------------------------------------------------------------------------- notebook copy

def prepare_notebook(src: Path, dst_dir: Path, parameters: dict | None = None, *, first_cell=None) -> Path:
    """Copy ``src`` into ``dst_dir`` with ``parameters`` injected as papermill does.

    The copy keeps the file name, has no outputs or execution counts, and names
    the ``python3`` kernel of this environment. ``first_cell`` (a code cell, e.g.
    :func:`uwbwb.classroom.hook_cell`) is put before the notebook's own cells.
    """
    from papermill.iorw import load_notebook_node, write_ipynb
    from papermill.parameterize import parameterize_notebook

    nb = load_notebook_node(str(src))
    if first_cell is not None:
        nb.cells.insert(0, first_cell)
    if parameters:
        nb = parameterize_notebook(nb, parameters, kernel_name="python3", language="python")
    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.outputs = []
            cell.execution_count = None
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3 (uwbwb)",
                                 "language": "python"}
    nb.metadata.pop("widgets", None)
    dst = Path(dst_dir) / Path(src).name
    write_ipynb(nb, str(dst))
    return dst


# --------------------------------------------------------------------------- server

def _terminate_with_parent() -> None:
    """In the child before exec (Linux): SIGTERM when the parent dies, even by SIGKILL.

    The server then shuts its kernels down itself, so a killed test run leaves
    nothing behind.
    """
    with contextlib.suppress(Exception):
        import ctypes
        PR_SET_PDEATHSIG = 1
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class LabServer:
    """``jupyter lab`` on loopback, serving ``root_dir``; use as a context manager.

    Everything it writes (runtime files, settings, workspaces, log) lives in a
    temporary folder removed on exit. :meth:`stop` shuts the server down through
    its API, then kills whatever is left of it and of its kernels.
    """

    def __init__(self, root_dir: Path, *, start_timeout_s: float = 120.0):
        self.root_dir = Path(root_dir)
        self.start_timeout_s = start_timeout_s
        self.token = secrets.token_hex(24)
        self.port: int | None = None
        self.proc: subprocess.Popen | None = None
        self._state_dir: Path | None = None
        self._log = None

    @property
    def base_url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    @property
    def log_path(self) -> Path:
        return self._state_dir / "server.log"

    def log_tail(self, n_lines: int = 40) -> str:
        try:
            return "\n".join(self.log_path.read_text(errors="replace").splitlines()[-n_lines:])
        except OSError:
            return "(no server log)"

    def lab_url(self, workspace: str = "uwbwb") -> str:
        """URL of JupyterLab in a fresh named workspace (no document open)."""
        return f"{self.base_url}/lab/workspaces/{workspace}?reset&token={self.token}"

    def api(self, method: str, path: str, timeout_s: float = 10.0):
        req = urllib.request.Request(f"{self.base_url}{path}", method=method,
                                     headers={"Authorization": f"token {self.token}"})
        with urllib.request.urlopen(req, timeout=timeout_s) as resp:
            body = resp.read()
        return json.loads(body) if body else None

    def start(self) -> "LabServer":
        self._state_dir = Path(tempfile.mkdtemp(prefix="uwbwb-lab-"))
        env = dict(os.environ)
        for var, sub in (("JUPYTER_RUNTIME_DIR", "runtime"), ("JUPYTER_CONFIG_DIR", "config"),
                         ("JUPYTERLAB_SETTINGS_DIR", "settings"),
                         ("JUPYTERLAB_WORKSPACES_DIR", "workspaces")):
            (self._state_dir / sub).mkdir()
            env[var] = str(self._state_dir / sub)
        for rel, values in LAB_SETTINGS.items():
            path = self._state_dir / "settings" / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(values))
        env["JUPYTER_PREFER_ENV_PATH"] = "1"  # this venv's kernelspec and lab extensions first
        env.pop("JUPYTER_TOKEN", None)
        self.port = _free_port()
        cmd = [sys.executable, "-m", "jupyter", "lab", "--no-browser",
               "--ServerApp.ip=127.0.0.1", f"--ServerApp.port={self.port}", "--ServerApp.port_retries=0",
               f"--IdentityProvider.token={self.token}", f"--ServerApp.root_dir={self.root_dir}",
               "--LabApp.expose_app_in_browser=True", "--LabApp.news_url=None",
               "--LabApp.check_for_updates_class=jupyterlab.NeverCheckForUpdate",
               "--LabApp.extension_manager=readonly", "--ServerApp.terminals_enabled=False"]
        if hasattr(os, "geteuid") and os.geteuid() == 0:  # containers and CI run as root
            cmd.append("--allow-root")
        self._log = open(self.log_path, "wb")
        self.proc = subprocess.Popen(cmd, env=env, stdin=subprocess.DEVNULL, stdout=self._log,
                                     stderr=subprocess.STDOUT, start_new_session=True,
                                     preexec_fn=_terminate_with_parent)
        deadline = time.monotonic() + self.start_timeout_s
        while True:
            if self.proc.poll() is not None:
                raise RuntimeError(f"jupyter lab exited with code {self.proc.returncode}:\n{self.log_tail()}")
            try:
                self.api("GET", "/api/status", timeout_s=2)
                return self
            except (urllib.error.URLError, ConnectionError, TimeoutError, OSError):
                pass
            if time.monotonic() > deadline:
                raise RuntimeError(f"jupyter lab did not answer within {self.start_timeout_s:.0f} s:\n"
                                   f"{self.log_tail()}")
            time.sleep(0.25)

    def shutdown_kernels(self) -> None:
        """Shut down every running kernel (between notebooks, to free CPU and memory)."""
        for kernel in self.api("GET", "/api/kernels"):
            with contextlib.suppress(urllib.error.URLError, OSError):
                self.api("DELETE", f"/api/kernels/{kernel['id']}", timeout_s=30)

    def stop(self) -> None:
        if self.proc is None:
            return
        proc, self.proc = self.proc, None
        try:
            import psutil
            try:
                descendants = psutil.Process(proc.pid).children(recursive=True)
            except psutil.Error:
                descendants = []
            if proc.poll() is None:
                with contextlib.suppress(urllib.error.URLError, OSError):
                    self.api("POST", "/api/shutdown", timeout_s=5)
                try:
                    proc.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    with contextlib.suppress(ProcessLookupError):
                        os.killpg(proc.pid, signal.SIGTERM)
                    try:
                        proc.wait(timeout=5)
                    except subprocess.TimeoutExpired:
                        with contextlib.suppress(ProcessLookupError):
                            os.killpg(proc.pid, signal.SIGKILL)
                        proc.wait(timeout=5)
            # Kernels run in sessions of their own: kill any the server left behind.
            for child in descendants:
                with contextlib.suppress(psutil.Error):
                    child.kill()
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(proc.pid, signal.SIGKILL)
        finally:
            if self._log is not None:
                self._log.close()
            shutil.rmtree(self._state_dir, ignore_errors=True)

    def __enter__(self) -> "LabServer":
        try:
            return self.start()
        except BaseException:
            self.stop()
            raise

    def __exit__(self, *exc) -> None:
        self.stop()


def widget_manager_versions(server: LabServer) -> tuple[str, str]:
    """``(served, installed)`` versions of the JupyterLab widget manager extension.

    *served* is what the running JupyterLab reports for
    ``@jupyter-widgets/jupyterlab-manager``; *installed* is the version of that
    extension in this environment's ``jupyterlab_widgets`` distribution, the one
    matched to its ``ipywidgets``. Raises AssertionError if the extension is not
    served, not enabled or broken.
    """
    from importlib.metadata import distribution

    name = "@jupyter-widgets/jupyterlab-manager"
    served = {e["name"]: e for e in server.api("GET", "/lab/api/extensions")}
    ext = served.get(name)
    assert ext is not None, f"JupyterLab does not serve {name}; it serves {sorted(served)}"
    assert ext["enabled"] and ext["status"] == "ok", f"{name} is not usable: {ext}"
    dist = distribution("jupyterlab_widgets")
    package_json = [f for f in dist.files or ()
                    if f.as_posix().endswith("labextensions/" + name + "/package.json")]
    assert package_json, f"jupyterlab_widgets {dist.version} ships no {name} extension"
    installed = json.loads(package_json[0].read_text())["version"]
    return ext["installed_version"], installed


# --------------------------------------------------------------------------- browser

def launch_chromium(playwright):
    """The system Chromium, headless, through Playwright."""
    if not CHROMIUM.exists():
        raise FileNotFoundError(f"{CHROMIUM} not found (apt-get install chromium)")
    return playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS, headless=True)


@contextlib.contextmanager
def lab_session(root_dir: Path):
    """``(server, page)`` for one folder of prepared notebooks: ``page`` shows JupyterLab (:func:`open_lab`), where
    :func:`open_and_run` opens the notebooks one after another; everything closed on exit."""
    from playwright.sync_api import sync_playwright

    with LabServer(root_dir) as server, sync_playwright() as pw:
        browser = launch_chromium(pw)
        try:
            page = browser.new_context(viewport={"width": 1400, "height": 1000}).new_page()
            page.set_default_timeout(30_000)
            open_lab(page, server)
            yield server, page
        finally:
            browser.close()


# --------------------------------------------------------------------------- page helpers

# State of the notebook at `path` as seen by JupyterLab: kernel status, executed cells,
# error outputs (from the model, so nothing is missed by rendering).
_JS_STATE = """(path) => {
  const app = window.jupyterapp;
  if (!app) return {phase: 'no app'};
  let nb = null;
  for (const w of app.shell.widgets('main')) { if (w.context && w.context.path === path) nb = w; }
  if (!nb || !nb.context.isReady) return {phase: 'opening', open: window.__uwbwbOpen || null};
  const sc = nb.sessionContext;
  const kernel = sc.session ? sc.session.kernel : null;
  const cells = nb.content.widgets.filter(c => c.model.type === 'code');
  const errors = [];
  cells.forEach((c, i) => {
    for (let k = 0; k < c.model.outputs.length; k++) {
      const output = c.model.outputs.get(k);
      if (output.type !== 'error') continue;     // no copy of every figure's data on every look
      const o = output.toJSON();
      errors.push(`code cell ${i + 1}: ${o.ename}: ${o.evalue}`);
    }
  });
  const pending = cells.findIndex(c => c.model.executionCount === null);
  return {phase: 'open', id: nb.id, kernel: kernel ? kernel.status : 'none', ready: sc.isReady,
          nCode: cells.length, pending: pending, errors: errors,
          runAll: window.__uwbwbRunAll || null};
}"""

_JS_OPEN = """(path) => {
  window.__uwbwbRunAll = null;
  window.__uwbwbOpen = 'opening';
  window.jupyterapp.commands.execute('docmanager:open', {path: path, factory: 'Notebook'}).then(
    () => { window.__uwbwbOpen = 'open'; }, err => { window.__uwbwbOpen = 'failed: ' + err; });
}"""

# Close the notebook at `path` without saving; true when no dialog is left on the page.
_JS_CLOSE = """(path) => {
  for (const w of window.jupyterapp.shell.widgets('main')) {
    if (w.context && w.context.path === path) { w.context.model.dirty = false; w.dispose(); }
  }
  return !document.querySelector('.jp-Dialog');
}"""

_JS_RUN_ALL = """async (id) => {
  const app = window.jupyterapp;
  app.shell.activateById(id);
  window.__uwbwbRunAll = 'running';
  app.commands.execute('notebook:run-all-cells').then(
    ok => { window.__uwbwbRunAll = ok === false ? 'stopped' : 'done'; },
    err => { window.__uwbwbRunAll = 'failed: ' + err; });
}"""

# Save the notebook at `path` (its outputs as the kernel left them) and wait until written.
_JS_SAVE = """async (path) => {
  for (const w of window.jupyterapp.shell.widgets('main')) {
    if (w.context && w.context.path === path) { await w.context.save(); return !w.context.model.dirty; }
  }
  return false;
}"""

# Text of every stderr output and of everything that looks like a widget failure.
_JS_PAGE_PROBLEMS = """() => {
  const out = [];
  for (const el of document.querySelectorAll(
      '.jp-OutputArea-output[data-mime-type="application/vnd.jupyter.stderr"]')) {
    const t = el.innerText;
    if (/Traceback|\\b[A-Z]\\w*(Error|Exception)\\b/.test(t)) out.push('stderr output: ' + t.slice(0, 2000));
  }
  if (document.body.innerText.includes('Error displaying widget'))
    out.push('"Error displaying widget" shown');
  for (const el of document.querySelectorAll('.uwbwb-error'))
    out.push('panel error: ' + el.innerText.slice(0, 2000));
  return out;
}"""

# A fingerprint of a panel's output: readout text and figure image.
_JS_PANEL_STATE = """(panel) => {
  const readout = panel.querySelector('.uwbwb-readout');
  const img = panel.querySelector('.uwbwb-figure img');
  const error = panel.querySelector('.uwbwb-error');
  return {readout: readout ? readout.innerText : null, img: img ? img.src : null,
          error: error ? error.innerText : null};
}"""

# Wait in the page (no round trip per look) until the panel's state (_JS_PANEL_STATE) differs from `before` or
# shows an error, then until it has not changed for `settleMs`, both within `timeoutMs`; the last state seen and
# when (ms after the call) it last changed. `changed` is false when nothing changed in time.
_JS_PANEL_UPDATE = """async (panel, [before, settleMs, timeoutMs]) => {
  const state = () => (""" + _JS_PANEL_STATE + """)(panel);
  const pause = () => new Promise(resolve => setTimeout(resolve, 10));
  const t0 = performance.now();
  let now = state();
  while (!now.error && now.readout === before.readout && now.img === before.img) {
    if (performance.now() - t0 > timeoutMs) return {state: now, changed: false, lastMs: null};
    await pause();
    now = state();
  }
  let last = performance.now();
  while (!now.error && performance.now() - last < settleMs && performance.now() - t0 < timeoutMs) {
    await pause();
    const next = state();
    if (next.readout !== now.readout || next.img !== now.img || next.error !== now.error) {
      now = next;
      last = performance.now();
    }
  }
  return {state: now, changed: true, lastMs: last - t0};
}"""


def _wait_for_widget_views(page, name: str) -> None:
    """Wait until no output shows "Loading widget..." (a model the front end never got)."""
    deadline = time.monotonic() + WIDGET_LOAD_TIMEOUT_S
    while page.evaluate("() => document.body.innerText.includes('Loading widget...')"):
        if time.monotonic() > deadline:
            raise AssertionError(f"{name}: a widget still shows 'Loading widget...' "
                                 f"{WIDGET_LOAD_TIMEOUT_S:.0f} s after the last cell ran (its model "
                                 "never reached the front end's widget manager)")
        time.sleep(0.1)


def _page_problems(page) -> list[str]:
    return page.evaluate(_JS_PAGE_PROBLEMS)


class _Console:
    """Collects the page's console errors and uncaught exceptions for failure messages, until :meth:`close`."""

    def __init__(self, page):
        self.messages: list[str] = []
        self._page = page
        self._listeners = {"console": lambda m: self.messages.append(f"console.{m.type}: {m.text}")
                           if m.type == "error" else None,
                           "pageerror": lambda e: self.messages.append(f"page error: {e}")}
        for event, listener in self._listeners.items():
            page.on(event, listener)

    def tail(self, n: int = 10) -> str:
        return "\n".join(self.messages[-n:]) or "(none)"

    def close(self) -> None:
        for event, listener in self._listeners.items():
            self._page.remove_listener(event, listener)


def open_lab(page, server: LabServer) -> None:
    """Load JupyterLab into ``page`` (a fresh workspace) and wait until it has restored its layout."""
    page.goto(server.lab_url(), wait_until="domcontentloaded", timeout=OPEN_TIMEOUT_S * 1000)
    deadline = time.monotonic() + OPEN_TIMEOUT_S
    while not page.evaluate("async () => !!window.jupyterapp && (await window.jupyterapp.restored, true)"):
        if time.monotonic() > deadline:
            raise AssertionError(f"JupyterLab did not load within {OPEN_TIMEOUT_S:.0f} s.\n"
                                 f"Server log:\n{server.log_tail()}")
        time.sleep(0.2)


def close_notebook(page, server: LabServer, name: str) -> None:
    """Close notebook ``name``'s tab without saving and shut the kernels down. Where a dialog is left open
    or the page broke, JupyterLab is loaded afresh, so that the next notebook starts on a clean page."""
    try:
        clean = page.evaluate(_JS_CLOSE, name)
    except Exception:
        clean = False
    server.shutdown_kernels()
    if not clean:
        open_lab(page, server)


def open_and_run(page, server: LabServer, name: str, *, timeout_s: float = RUN_TIMEOUT_S) -> float:
    """Open notebook ``name`` (relative to the server root) in JupyterLab in ``page``, run all cells, wait until
    done; :func:`close_notebook` closes it.

    Returns the time from "run all" to the last cell finishing, in seconds.
    Raises AssertionError (naming the notebook) on a cell error, a dead kernel or
    a timeout.
    """
    page.evaluate(_JS_OPEN, name)
    deadline = time.monotonic() + min(timeout_s, OPEN_TIMEOUT_S)
    state: dict = {}
    while True:  # open, kernel started and idle
        state = page.evaluate(_JS_STATE, name)
        if state.get("phase") == "open" and state["ready"] and state["kernel"] == "idle":
            break
        if str(state.get("open")).startswith("failed"):
            raise AssertionError(f"{name}: JupyterLab could not open it: {state['open']}")
        if time.monotonic() > deadline:
            raise AssertionError(
                f"{name}: JupyterLab did not open the notebook with an idle kernel within "
                f"{OPEN_TIMEOUT_S:.0f} s (state {state}; a kernel-selection dialog means kernel "
                f"'python3' is missing).\nServer log:\n{server.log_tail()}")
        time.sleep(0.2)
    t0 = time.monotonic()
    deadline = t0 + timeout_s
    page.evaluate(_JS_RUN_ALL, state["id"])
    while True:
        time.sleep(0.25)
        state = page.evaluate(_JS_STATE, name)
        if state.get("errors"):
            raise AssertionError(f"{name}: cell error while running all cells:\n  "
                                 + "\n  ".join(state["errors"]))
        run_all = str(state.get("runAll"))
        if run_all.startswith("failed"):
            raise AssertionError(f"{name}: 'run all cells' failed: {run_all}")
        if state.get("kernel") in ("dead", "autorestarting", "restarting", "unknown"):
            raise AssertionError(f"{name}: the kernel is {state['kernel']} while running code cell "
                                 f"{state.get('pending', -1) + 1}.\nServer log:\n{server.log_tail()}")
        if run_all in ("done", "stopped") and state.get("kernel") == "idle":
            if state.get("pending") == -1:
                return time.monotonic() - t0
            if run_all == "stopped":
                raise AssertionError(f"{name}: 'run all cells' stopped before code cell "
                                     f"{state['pending'] + 1} of {state['nCode']}")
        if time.monotonic() > deadline:
            raise AssertionError(f"{name}: not finished within {timeout_s:.0f} s: code cell "
                                 f"{state.get('pending', -1) + 1} of {state.get('nCode')} has not finished "
                                 f"(kernel {state.get('kernel')}).")


@dataclass
class ControlChange:
    """One control change of one panel and what it did."""

    control: str
    action: str
    direction: int
    latency_s: float
    readout_before: str | None
    readout_after: str | None
    figure_changed: bool


def change_control(page, panel, *, name: str, index: int, direction: int = +1,
                   timeout_s: float = UPDATE_TIMEOUT_S) -> ControlChange:
    """Change one control of ``panel`` (a locator) like a user, wait for the panel to update.

    The control is the panel's first slider (moved one step with an arrow key,
    ``direction`` +1 right, -1 left, reversed at the end of its range; the
    direction used is returned), else its first dropdown (next option), else its
    first number box (value + 1 and Enter). Latency is measured from the key
    press / selection to the first DOM change of the readout or figure.
    Returns what happened; raises AssertionError naming the notebook ``name``
    when the panel shows an error or nothing updated within ``timeout_s``.
    """
    where = f"{name}: panel {index + 1}"
    before = panel.evaluate(_JS_PANEL_STATE)
    controls = panel.locator(".uwbwb-controls")
    handle = controls.locator(".noUi-handle").first
    select = controls.locator("select").first
    number = controls.locator("input[type=number]").first
    t0 = time.monotonic()
    if handle.count():
        label = _control_label(handle, ".widget-slider")
        now, lo, hi = (float(handle.get_attribute(a)) for a in
                       ("aria-valuenow", "aria-valuemin", "aria-valuemax"))
        if (direction > 0 and now >= hi) or (direction < 0 and now <= lo):
            direction = -direction
        key = "ArrowRight" if direction > 0 else "ArrowLeft"
        handle.focus()
        t0 = time.monotonic()
        handle.press(key)
        action = f"slider {key}"
    elif select.count():
        label = _control_label(select, ".widget-dropdown")
        options = select.locator("option").all_text_contents()
        current = select.evaluate("s => s.selectedIndex")
        if len(options) < 2:
            raise AssertionError(f"{where}: its only control, dropdown {label!r}, has one option")
        target = options[(current + 1) % len(options)]
        t0 = time.monotonic()
        select.select_option(label=target)
        action = f"dropdown -> {target!r}"
    elif number.count():
        label = _control_label(number, ".widget-inline-hbox")
        value = int(float(number.input_value())) + 1
        number.fill(str(value))
        t0 = time.monotonic()
        number.press("Enter")
        action = f"number box -> {value}"
    else:
        raise AssertionError(f"{where}: no slider, dropdown or number box to change")
    # The first update and the rest of it (readout and figure arrive as separate messages), watched in the page:
    # the latency runs to the last change seen before the panel is quiet for SETTLE_S.
    waited = time.monotonic()
    update = panel.evaluate(_JS_PANEL_UPDATE, [before, 1000 * SETTLE_S, 1000 * max(t0 + timeout_s - waited, 0.0)])
    after = update["state"]
    if after["error"]:
        raise AssertionError(f"{where}: error after changing {label!r} ({action}):\n{after['error']}")
    if not update["changed"]:
        raise AssertionError(f"{where}: changed {label!r} ({action}) but neither the readout nor "
                             f"the figure updated within {timeout_s:.0f} s")
    latency = waited - t0 + update["lastMs"] / 1000
    return ControlChange(label, action, direction, latency, before["readout"], after["readout"],
                         after["img"] != before["img"])


def _control_label(element, container: str) -> str:
    box = element.locator(f"xpath=ancestor::*[contains(@class, '{container.strip('.')}')][1]")
    label = box.locator("label").first
    return label.inner_text().strip() if label.count() else "?"


# --------------------------------------------------------------------------- the check

@dataclass
class NotebookReport:
    """What :func:`check_notebook` saw."""

    name: str
    run_s: float
    panels: list[ControlChange] = field(default_factory=list)
    screenshots: list[Path] = field(default_factory=list)
    output_text: str = ""


def check_notebook(server: LabServer, page, name: str, *, out_dir: Path | None = None,
                   timeout_s: float = RUN_TIMEOUT_S,
                   update_timeout_s: float = UPDATE_TIMEOUT_S, save: bool = False) -> NotebookReport:
    """Run notebook ``name`` (already in the server's root) in JupyterLab in ``page`` and check its panels.

    Asserts: no error output or error-looking stderr, no "Error displaying widget",
    no panel error, at least one ``uwbwb-panel``, and every panel updates its readout
    or figure after one control change. The text of every cell output after the run is in the report's
    ``output_text``. Screenshots (whole panel before and after,
    figure before) and a ``report.json`` go to ``out_dir``. Failures raise
    AssertionError whose message starts with the notebook's name. The notebook is
    closed and its kernel shut down afterwards (:func:`close_notebook`). ``save=True``: once every cell has run and
    before any control moves, JupyterLab saves the notebook with its outputs
    over the copy in the server's root.
    """
    stem = Path(name).stem
    out_dir = Path(out_dir) if out_dir is not None else OUTPUT_DIR / stem
    out_dir.mkdir(parents=True, exist_ok=True)
    for old in [*out_dir.glob("panel*.png"), out_dir / "failure.png", out_dir / "report.json"]:
        old.unlink(missing_ok=True)  # nothing from an earlier run may pass for this one's
    console = _Console(page)
    try:
        try:
            run_s = open_and_run(page, server, name, timeout_s=timeout_s)
            report = NotebookReport(name, run_s)
            _wait_for_widget_views(page, name)
            report.output_text = "\n".join(page.locator(".jp-OutputArea-output").all_inner_texts())
            if save and not page.evaluate(_JS_SAVE, name):
                raise AssertionError(f"{name}: JupyterLab did not save the executed notebook")
            problems = _page_problems(page)
            if problems:
                raise AssertionError(f"{name}: after running all cells:\n  " + "\n  ".join(problems))
            panels = page.locator(".uwbwb-panel")
            n_panels = panels.count()
            if n_panels == 0:
                raise AssertionError(f"{name}: no uwbwb-panel was rendered (is the widget manager "
                                     f"missing?). Browser console:\n{console.tail()}")
            for i in range(n_panels):
                panel = panels.nth(i)
                panel.scroll_into_view_if_needed()
                shot = out_dir / f"panel{i + 1}-before.png"
                panel.screenshot(path=str(shot))
                report.screenshots.append(shot)
                figure = panel.locator(".uwbwb-figure img").first
                if figure.count():
                    shot = out_dir / f"panel{i + 1}-figure.png"
                    figure.screenshot(path=str(shot))
                    report.screenshots.append(shot)
                report.panels.append(change_control(page, panel, name=name, index=i,
                                                    timeout_s=update_timeout_s))
                shot = out_dir / f"panel{i + 1}-after.png"
                panel.screenshot(path=str(shot))
                report.screenshots.append(shot)
            problems = _page_problems(page)
            if problems:
                raise AssertionError(f"{name}: after changing controls:\n  " + "\n  ".join(problems))
        except AssertionError:
            with contextlib.suppress(Exception):
                page.screenshot(path=str(out_dir / "failure.png"), full_page=True)
            raise
        except Exception as exc:  # Playwright timeouts and the like: still name the notebook
            with contextlib.suppress(Exception):
                page.screenshot(path=str(out_dir / "failure.png"), full_page=True)
            raise AssertionError(f"{name}: {type(exc).__name__}: {exc}\nBrowser console:\n"
                                 f"{console.tail()}") from exc
        (out_dir / "report.json").write_text(json.dumps(
            {"notebook": name, "run_s": report.run_s,
             "panels": [vars(p) for p in report.panels]}, indent=2))
        return report
    finally:
        console.close()
        with contextlib.suppress(Exception):
            close_notebook(page, server, name)

