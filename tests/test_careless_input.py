"""What a careless user types into ``reproduce``: every notebook parameter has a spec, values reach the
notebook with their type, --quick never drops an explicit value, a bad scheduler fails promptly, and the
output holds only the workbench's own lines."""

from __future__ import annotations

import ast
import json
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import nbformat
import pytest

from uwbwb import cli
from uwbwb import notebook_params as nbp
from uwbwb import reproduce as rp
from tests.test_reproduce import _notebook
from uwbwb.datasets.discovery import PROJECT_ROOT

NOTEBOOKS_DIR = PROJECT_ROOT / "notebooks"
NOTEBOOKS = sorted(NOTEBOOKS_DIR.glob("*.ipynb"))


@pytest.fixture(autouse=True)
def _in_the_project(monkeypatch):
    """The command line finds notebooks/ in the working directory: run these from the project root."""
    monkeypatch.chdir(PROJECT_ROOT)


def _parameters_cell(path: Path):
    nb = nbformat.read(path, as_version=4)
    return next(c for c in nb.cells if "parameters" in c.metadata.get("tags", []))


def _inspected(path: Path) -> list[str]:
    """Parameter names as papermill reads them (as tests/test_notebooks.py does)."""
    from papermill.translators import PythonTranslator

    return [p.name for p in PythonTranslator.inspect(_parameters_cell(path))]


# --------------------------------------------------------------------------- the table is complete

@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_every_notebook_parameter_has_a_spec_that_its_default_satisfies(path):
    assert path.stem in nbp.SPECS, f"{path.stem}: add its parameters to uwbwb.notebook_params.SPECS"
    table = nbp.COMMON | nbp.SPECS[path.stem]
    names = _inspected(path)
    missing = [n for n in names if n not in table]
    assert not missing, f"{path.stem}: parameters without a spec in uwbwb.notebook_params.SPECS: {missing}"
    stale = sorted(set(nbp.SPECS[path.stem]) - set(names))
    assert not stale, f"{path.stem}: SPECS lists parameters the notebook no longer declares: {stale}"
    defaults = rp.notebook_parameters(path)
    for name in names:
        value = table[name].validate(defaults[name], name)
        assert value == defaults[name] and type(value) is type(defaults[name]), name


def _fast_assigned(path: Path, names: set[str]) -> set[str]:
    """Parameters that the notebook's code reassigns under ``if FAST:`` or in ``X = ... FAST ...``."""
    found = set()
    for cell in nbformat.read(path, as_version=4).cells:
        if cell.cell_type != "code" or "parameters" in cell.metadata.get("tags", []):
            continue
        source = "\n".join(ln for ln in cell.source.splitlines() if not ln.lstrip().startswith(("%", "!")))
        try:
            tree = ast.parse(source)
        except SyntaxError:
            continue
        for node in ast.walk(tree):
            mentions_fast = lambda n: any(isinstance(x, ast.Name) and x.id == "FAST" for x in ast.walk(n))  # noqa: E731
            targets = []
            if isinstance(node, ast.If) and mentions_fast(node.test):
                targets = [t for stmt in node.body + node.orelse for a in ast.walk(stmt)
                           if isinstance(a, ast.Assign) for t in a.targets]
            elif isinstance(node, ast.Assign) and mentions_fast(node.value):
                targets = node.targets
            for t in targets:
                for x in ast.walk(t):
                    if isinstance(x, ast.Name) and x.id in names:
                        found.add(x.id)
    return found


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_parameters_that_fast_mode_reassigns_are_declared_so(path):
    """A parameter the notebook replaces or caps under FAST must say so, or --quick would drop it silently."""
    table = nbp.COMMON | nbp.SPECS.get(path.stem, {})
    reassigned = _fast_assigned(path, set(_inspected(path)))
    undeclared = sorted(n for n in reassigned if table[n].fast is None and table[n].fast_cap is None)
    assert not undeclared, f"{path.stem}: FAST mode reassigns {undeclared}; give their specs fast= or fast_cap="


# --------------------------------------------------------------------------- values arrive typed (item 1)

def _samples(spec: nbp.Spec, default) -> list[str]:
    """Texts a user could type for a parameter: a short tuple (as tuple and as list), a scalar, None."""
    def item(s):
        if s.choices is not None:
            return s.choices[-1]
        if s.kind == "str":
            return "t0"
        if s.kind == "int":
            return max(s.lo or 0, 1)
        if s.kind == "float":
            lo, hi = s.lo if s.lo is not None else 0.0, s.hi if s.hi is not None else 10.0
            return (lo + min(hi, lo + 10.0)) / 2
        raise AssertionError(s.kind)

    out = []
    if spec.kind == "tuple":
        values = tuple(default[:2]) if isinstance(default, tuple) and default else (item(spec.item),)
        if not _passes(spec, repr(values)):                    # a check on the whole tuple: the default passes
            values = tuple(default)
        out += [repr(values), repr(list(values))]
    elif spec.kind == "str":
        checked = [t for t in ("local", str(Path(__file__).parent)) if _passes(spec, t)]
        out.append(checked[0] if spec.check is not None else "some folder")
    else:
        out.append(repr(item(spec)))
    if spec.none is not None:
        out.append("None")
    return out


def _passes(spec, text: str) -> bool:
    try:
        spec.parse(text)
    except ValueError:
        return False
    return True


_TYPED = [(path, name, text) for path in NOTEBOOKS
          for name, default in rp.notebook_parameters(path).items()
          if name not in rp.RESERVED_PARAMETERS and (default is None or isinstance(default, (tuple, list)))
          for text in _samples(nbp.specs_for(path.stem, {name: default})[name], default)]
_TYPED += [(NOTEBOOKS_DIR / "01_set_noise_pf.ipynb", "SIGMA_D_CMPS", "(2.5, 4, 40)"),
           (NOTEBOOKS_DIR / "01_set_noise_pf.ipynb", "SIGMA_D_CMPS", "(2, 4, 30)"),
           (NOTEBOOKS_DIR / "04_doppler_beacons.ipynb", "N_BRUTE", "1e7")]


@pytest.mark.parametrize("path, name, text", _TYPED, ids=[f"{p.stem[:2]}-{n}-{t}" for p, n, t in _TYPED])
def test_a_value_reaches_the_notebook_with_the_type_of_its_spec(path, name, text):
    """Run the parameters cell and the injected cell in-process, as the kernel does first."""
    params = rp.resolve_parameters([path], text={name: text})[path]
    namespace: dict = {}
    exec(_parameters_cell(path).source + "\n" + rp.injected_source(params), namespace)
    spec = nbp.specs_for(path.stem, {name: None})[name]
    got = namespace[name]
    assert got == spec.parse(text, name)
    if got is None:
        assert text == "None"
    elif spec.kind == "tuple":
        assert isinstance(got, tuple), f"{name} arrived as {type(got).__name__}"
        assert all(spec.item.validate(v, name) == v and type(v) is type(spec.item.validate(v, name)) for v in got)
    else:
        assert type(got) is {"int": int, "float": float, "str": str, "bool": bool}[spec.kind], type(got)


def test_sigma_d_accepts_non_integer_speeds_and_they_arrive_as_a_tuple_of_floats():
    path = NOTEBOOKS_DIR / "01_set_noise_pf.ipynb"
    params = rp.resolve_parameters([path], text={"SIGMA_D_CMPS": "(2.5, 4, 40)"})[path]
    assert params == {"SIGMA_D_CMPS": (2.5, 4.0, 40.0)}
    assert "SIGMA_D_CMPS = (2.5, 4.0, 40.0)" in rp.injected_source(params)


def test_sigma_d_without_a_value_in_the_papers_band_is_refused_before_the_run():
    """The old README example (2.5, 4) used to pass the check and kill notebook 01 at its band table."""
    from uwbwb.experiments.setnoise import BAND_MPS
    assert tuple(100 * b for b in BAND_MPS) == nbp.SIGMA_D_BAND_CMPS
    path = NOTEBOOKS_DIR / "01_set_noise_pf.ipynb"
    with pytest.raises(ValueError, match=r"no value in the paper's band 30–50 cm/s.*add one, e.g. \(2\.5, 4\.0, 40\.0\)"):
        rp.resolve_parameters([path], text={"SIGMA_D_CMPS": "(2.5, 4)"})
    assert rp.resolve_parameters([path], text={"SIGMA_D_CMPS": "(50, 80)"})[path] == {"SIGMA_D_CMPS": (50.0, 80.0)}


def test_numpy_scalars_and_paths_from_python_are_the_values_they_stand_for(tmp_path):
    """A Python caller's np.int64, np.float64, np.bool_ and Path are accepted and arrive as int, float, bool, str."""
    import numpy as np

    assert type(nbp.integer(1).validate(np.int64(3), "N")) is int
    assert type(nbp.real(0.0).validate(np.float64(2.5), "X")) is float
    assert nbp.flag().validate(np.bool_(True), "FAST") is True
    assert nbp.text(none="x").validate(tmp_path, "DATA_DIR") == str(tmp_path)
    with pytest.raises(ValueError, match="expected an integer"):
        nbp.integer(1).validate(np.float64(2.5), "N")


def test_a_tag_named_twice_is_refused_before_the_run():
    path = NOTEBOOKS_DIR / "03_ekf_motion_models.ipynb"
    with pytest.raises(ValueError, match=r"-p LIAS_TAGS .*distinct values"):
        rp.resolve_parameters([path], text={"LIAS_TAGS": "('t0', 't0')"})
    assert rp.resolve_parameters([path], text={"LIAS_TAGS": "('t0', 't1')"})[path] == {"LIAS_TAGS": ("t0", "t1")}


def test_the_parameter_examples_of_the_readme_and_the_help_are_accepted_as_written():
    import re
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    helptext = " ".join(cli._build_parser()[1]["reproduce"].format_help().split())
    examples = re.findall(r"-p ([A-Z_]+) \"([^\"]+)\"", readme) + re.findall(r"-p ([A-Z_]+) '([^']+)'", readme + helptext)
    examples += re.findall(r"`-p ([A-Z_]+) ([^`\s\"']+)`", readme)
    examples = [(n, v) for n, v in examples if n not in ("NAME", "KEY")]          # the placeholders
    assert ("SIGMA_D_CMPS", "(2.5, 4, 40)") in examples and len(examples) >= 4, examples
    for name, value in examples:
        declaring = [p for p in NOTEBOOKS if name in rp.notebook_parameters(p)]
        assert declaring, f"README/--help example -p {name} {value}: no notebook declares {name}"
        for path in declaring:
            rp.resolve_parameters([path], text={name: value})     # raises naming the parameter if it does not fit


def test_the_injected_cell_refuses_values_that_are_not_literals():
    assert rp.injected_source({"A": (1, 2), "B": "x", "C": None}).splitlines()[1:] == \
        ["A = (1, 2)", "B = 'x'", "C = None"]
    for bad in (float("nan"), float("inf"), object()):
        with pytest.raises(ValueError, match="parameter X="):
            rp.injected_source({"X": bad})


def test_the_injected_cell_follows_the_parameters_cell_and_replaces_an_earlier_one():
    nb = nbformat.v4.new_notebook()
    cell = nbformat.v4.new_code_cell("A = 1")
    cell.metadata["tags"] = ["parameters"]
    nb.cells = [nbformat.v4.new_markdown_cell("# t"), cell, nbformat.v4.new_code_cell("print(A)")]
    rp.parameterized(nb, {"A": (1, 2), "B": {1, 2}})
    rp.parameterized(nb, {"A": 3})
    assert [c.source.splitlines()[-1] for c in nb.cells] == ["# t", "A = 1", "A = 3", "print(A)"]
    assert nb.cells[2].metadata["tags"] == [rp.INJECTED_TAG] and nb.metadata.papermill["parameters"] == {"A": 3}


# --------------------------------------------------------------------------- what each parameter accepts (item 2)

@pytest.fixture
def no_run(monkeypatch):
    """Record what each notebook would receive; run nothing."""
    received = {}

    def fake_run(source, out_dir, parameters, **kwargs):
        received[source.stem] = dict(parameters)
        return rp.NotebookRun(notebook=source.stem, source=source, executed=out_dir / "x.ipynb", html=None,
                              summary=out_dir / "x.json", seconds=0.0, error=None)

    monkeypatch.setattr(rp, "run_notebook", fake_run)
    return received


@pytest.mark.parametrize("only, name, text, message", [
    ("04", "N_BRUTE", "9" * 5000, "-p N_BRUTE 9999"),
    ("04", "N_BRUTE", "9" * 30, "expected an integer ≥ 1 and ≤ 2**63 - 1, or None (1e9 draws (full), 2e7 (FAST))"),
    ("04", "N_BRUTE", "0", "expected an integer ≥ 1"),
    ("04", "N_BRUTE", "lots", "expected an integer ≥ 1"),
    ("04", "TEMPERATURE_C", "-300", "expected a number ≥ -50 and ≤ 60"),
    ("03", "GATE_PROB", "1.5", "expected a number > 0 and < 1, or None (no gate)"),
    ("03", "LIAS_TAGS", "t0", "expected a tuple"),
    ("05", "GRADE", "military", "expected one of 'consumer', 'industrial', 'tactical'"),
    ("01", "SIGMA_D_CMPS", "(4, 2)", "strictly increasing"),
    ("01", "SIGMA_D_CMPS", "(0, 2)", "each a number > 0"),
    ("01", "SIGMA_D_CMPS", "()", "expected a tuple"),
    ("02", "TOURS", "(1, 4)", "each one of 1, 2, 3"),
    ("02", "DIM", "4", "expected one of 2, 3"),
    ("00", "SEED", "-1", "expected an integer ≥ 0"),
    ("00", "RECORDING", "", "expected non-empty text"),
    ("00", "DASK_SCHEDULER", "notanaddress", "scheduler 'notanaddress' is not an address"),
    ("00", "DATA_DIR", "/no/such/folder", "DATA_DIR /no/such/folder: does not exist"),
    ("01", "DATA_DIR", __file__, "is a file, not a folder"),
])
def test_a_value_outside_its_spec_stops_reproduce_naming_the_parameter(only, name, text, message, no_run, capsys,
                                                                       tmp_path):
    assert cli.main(["reproduce", "--only", only, "--out", str(tmp_path / "out"), "-p", name, text]) == 2
    err = capsys.readouterr().err
    assert message in err and f"-p {name}" in err and no_run == {}
    assert len([ln for ln in err.splitlines() if ln.startswith("python -m uwbwb reproduce: error:")]) == 1
    assert len(err) < 1000                            # a huge value is not copied into the message


@pytest.mark.parametrize("only, name, text, expected", [
    ("04", "N_BRUTE", "1e7", 10_000_000),
    ("04", "N_BRUTE", "None", None),
    ("03", "GATE_PROB", "0.999", 0.999),
    ("03", "GATE_PROB", "None", None),
    ("03", "LIAS_TAGS", "['t1']", ("t1",)),
    ("00", "DATA_DIR", "None", None),
    ("00", "DATA_DIR", str(Path(__file__).parent), str(Path(__file__).parent)),
    ("02", "STATIC_SESSION", "8.20", "8.20"),
])
def test_values_inside_their_spec_are_passed_typed(only, name, text, expected, no_run, tmp_path):
    assert cli.main(["reproduce", "--only", only, "--out", str(tmp_path), "-p", name, text]) == 0
    (got,) = no_run.values()
    assert got[name] == expected and type(got[name]) is type(expected)


# --------------------------------------------------------------------------- --quick and explicit values (item 3)

@pytest.mark.parametrize("argv, message", [
    (["--quick", "-p", "FAST", "False"], "--quick sets FAST=True, but FAST=False was given too"),
    (["--quick", "--only", "02", "-p", "TOURS", "(1, 2)"],
     "TOURS=(1, 2) would not be used: with FAST=True the notebook runs tour 2 only"),
    (["--only", "02", "-p", "FAST", "True", "-p", "TOURS", "(1, 2)"], "TOURS=(1, 2) would not be used"),
    (["--quick", "--only", "01", "-p", "SIGMA_D_CMPS", "(2, 4, 40)"], "runs its own CI-sized sweep"),
    (["--quick", "--only", "03", "-p", "SIM_DURATION_S", "100"],
     "SIM_DURATION_S=100.0 would not be used: with FAST=True the notebook lowers SIM_DURATION_S to 60"),
    (["--quick", "--only", "05", "-p", "STATIC_S", "60"], "lowers STATIC_S to 20"),
    # class mode sets its own lecture sizes: below FAST's cap is still not what a CLASS run uses
    (["--only", "03", "-p", "CLASS", "True", "-p", "SIM_DURATION_S", "50"],
     "SIM_DURATION_S=50.0 would not be used: with CLASS=True the notebook picks its own lecture sizes"),
    (["--only", "02", "-p", "CLASS", "True", "-p", "TOURS", "(1,)"], "with CLASS=True"),
])
def test_quick_never_drops_an_explicit_value(argv, message, no_run, capsys, tmp_path):
    assert cli.main(["reproduce", "--out", str(tmp_path / "out"), *argv]) == 2
    assert message in capsys.readouterr().err and no_run == {}


@pytest.mark.parametrize("argv, name, expected", [
    (["--quick", "--only", "03", "-p", "SIM_DURATION_S", "30"], "SIM_DURATION_S", 30.0),   # below FAST's cap
    (["--quick", "--only", "04", "-p", "N_BRUTE", "1000"], "N_BRUTE", 1000),                # FAST uses it as given
    (["--quick", "--only", "00", "-p", "FAST", "True"], "FAST", True),
    (["--only", "02", "-p", "TOURS", "(1, 2)"], "TOURS", (1, 2)),                           # full mode runs them
    (["--only", "04", "-p", "CLASS", "True", "-p", "N_BRUTE", "1000"], "N_BRUTE", 1000),    # class mode uses it too
])
def test_explicit_values_that_hold_under_fast_are_passed(argv, name, expected, no_run, tmp_path):
    assert cli.main(["reproduce", "--out", str(tmp_path), *argv]) == 0
    (got,) = no_run.values()
    assert got[name] == expected and got.get("FAST", False) is ("--quick" in argv or "FAST" in argv)


def test_reproduce_refuses_quick_with_fast_false_from_python(tmp_path):
    with pytest.raises(ValueError, match="--quick sets FAST=True"):
        rp.reproduce(quick=True, only=["00"], out=tmp_path, parameters={"FAST": False})


# --------------------------------------------------------------------------- a scheduler that is not there (item 5)

def _not_dask_server():
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)

    def serve():
        while True:
            try:
                conn, _ = srv.accept()
            except OSError:
                return
            conn.sendall(b"SSH-2.0-OpenSSH_9.6\r\n")

    threading.Thread(target=serve, daemon=True).start()
    return srv


def _refused_address():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp://127.0.0.1:{s.getsockname()[1]}"


@pytest.mark.parametrize("case", ["not dask", "refused", "malformed", "parameter"])
def test_reproduce_with_a_bad_scheduler_exits_promptly_with_one_line(case, tmp_path):
    pytest.importorskip("distributed", reason="dask.distributed is not installed")
    server = _not_dask_server() if case == "not dask" else None
    address = {"not dask": f"tcp://127.0.0.1:{server.getsockname()[1] if server else 0}",
               "refused": _refused_address(), "malformed": "notanaddress",
               "parameter": _refused_address()}[case]
    option = ["-p", "DASK_SCHEDULER", address] if case == "parameter" else ["--scheduler", address]
    try:
        done = subprocess.run([sys.executable, "-m", "uwbwb", "reproduce", "--only", "00", "--out",
                               str(tmp_path / "out"), "--scheduler-timeout", "2", *option],
                              capture_output=True, text=True, timeout=15, cwd=PROJECT_ROOT)
    finally:
        if server is not None:
            server.close()
    lines = [ln for ln in (done.stdout + done.stderr).splitlines() if ln.strip()]
    errors = [ln for ln in lines if "error:" in ln]
    assert done.returncode != 0 and len(errors) == 1, lines
    assert (address if case != "malformed" else "'notanaddress'") in errors[0]
    expected = {"not dask": "something accepts connections there but", "refused": "connection refused",
                "malformed": "is not an address", "parameter": "connection refused"}[case]
    assert expected in errors[0]
    assert not list((tmp_path / "out").glob("*.ipynb"))     # no notebook ran


# --------------------------------------------------------------------------- only the workbench's lines (item 9)

TINY_PARAMS = "FAST = False\nSEED = 0\nDATA_DIR = None\nSUMMARY_PATH = None\nTOURS = (1, 2, 3)\nTAGS = None\n"
TINY_BODY = """\
import json, os
timeout = os.environ.get("UWBWB_SCHEDULER_TIMEOUT_S")
rows = [{"notebook": "01_tiny", "quantity": "tours", "value": len(TOURS), "unit": "",
         "paper_value": None, "data": f"{type(TOURS).__name__} {type(TAGS).__name__} {timeout}", "kind": "reproduced",
         "mode": "FAST" if FAST else "full"}]
with open(SUMMARY_PATH, "w") as fh:
    json.dump(rows, fh)
"""


@pytest.mark.notebook
def test_reproduce_prints_no_kernel_transport_warning_and_tuples_arrive_as_tuples(tmp_path, monkeypatch, capfd):
    folder = tmp_path / "notebooks"
    folder.mkdir()
    _notebook(folder / "01_tiny.ipynb", TINY_PARAMS, TINY_BODY)
    monkeypatch.setattr(rp, "NOTEBOOKS_DIR", folder)
    out = tmp_path / "out"
    code = cli.main(["reproduce", "--quick", "--out", str(out), "-p", "TOURS", "(1, 2)", "-p", "TAGS", "('a', 'b')",
                     "--timeout", "120", "--scheduler-timeout", "2.5"])
    printed = capfd.readouterr()
    assert code == 0, printed
    assert "without encryption" not in printed.out + printed.err
    assert "WARNING" not in printed.err
    (row,) = json.loads((out / "summary.json").read_text())
    assert row["value"] == 2 and row["data"] == "tuple tuple 2.5"     # typed values; the timeout reached the kernel
    executed = nbformat.read(out / "01_tiny.ipynb", as_version=4)
    injected = [c for c in executed.cells if "injected-parameters" in c.metadata.get("tags", [])]
    assert len(injected) == 1 and "TOURS = (1, 2)" in injected[0].source
    assert executed.metadata.papermill["input_path"] == str(folder / "01_tiny.ipynb")


def test_the_scheduler_timeout_reaches_the_kernels(monkeypatch, tmp_path):
    seen = {}

    def fake_run(source, out_dir, parameters, **kwargs):
        seen[source.stem] = kwargs.get("kernel_env")
        return rp.NotebookRun(notebook=source.stem, source=source, executed=out_dir / "x.ipynb", html=None,
                              summary=out_dir / "x.json", seconds=0.0, error=None)

    monkeypatch.setattr(rp, "run_notebook", fake_run)
    rp.reproduce(only=["00"], out=tmp_path, scheduler_timeout_s=2.5)
    (env,) = seen.values()
    assert env["UWBWB_SCHEDULER_TIMEOUT_S"] == "2.5" and set(env) == {"UWBWB_SCHEDULER_TIMEOUT_S", "UWBWB_READ_LOG"}
    with pytest.raises(ValueError, match="timeout_s must be positive"):
        rp.reproduce(only=["00"], out=tmp_path, scheduler_timeout_s=-1)


def test_reproduce_takes_the_notebooks_from_a_folder_given_on_the_command_line(no_run, tmp_path, monkeypatch, capsys):
    """--notebooks-dir runs the notebooks of that folder from any working directory; a folder that does not
    exist is refused before anything runs."""
    import shutil

    src = tmp_path / "elsewhere"
    src.mkdir()
    shutil.copy(NOTEBOOKS_DIR / "00_quickstart.ipynb", src / "00_quickstart.ipynb")
    monkeypatch.chdir(tmp_path)                               # no notebooks/ here
    assert cli.main(["reproduce", "--notebooks-dir", str(src), "--out", str(tmp_path / "out")]) == 0
    assert list(no_run) == ["00_quickstart"]
    assert cli.main(["reproduce", "--notebooks-dir", str(tmp_path / "missing"), "--out", str(tmp_path / "o2")]) == 2
    assert "--notebooks-dir" in capsys.readouterr().err and not (tmp_path / "o2").exists()


def test_a_second_run_into_the_same_folder_is_refused_while_the_first_lives(no_run, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    hold = ("import fcntl, os, sys, time; f = open(sys.argv[1], 'a+'); fcntl.flock(f, fcntl.LOCK_EX); "
            "f.write(str(os.getpid())); f.flush(); print('held', flush=True); time.sleep(60)")
    holder = subprocess.Popen([sys.executable, "-c", hold, str(out / ".reproduce.lock")], stdout=subprocess.PIPE,
                              text=True)                               # a live run holds the folder
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(ValueError, match=rf"another reproduce \(process {holder.pid}\) is writing into this"):
            rp.reproduce(only=["00"], out=out)
        assert not no_run
    finally:
        holder.kill()
        holder.wait()
    assert (out / ".reproduce.lock").exists()                         # left by a run that was killed: taken over
    rp.reproduce(only=["00"], out=out)
    assert list(no_run) == ["00_quickstart"] and not (out / ".reproduce.lock").exists()


def test_an_interrupted_run_leaves_no_ok_summary_and_says_it_stopped(monkeypatch, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").write_text("[]")                          # an earlier run's summary
    (out / "summary.md").write_text("all ok")
    calls = []

    def fake_run(source, out_dir, parameters, **kwargs):
        calls.append(source.stem)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return rp.NotebookRun(notebook=source.stem, source=source, executed=out_dir / "x.ipynb", html=None,
                              summary=out_dir / "x.json", seconds=0.0, error=None)

    monkeypatch.setattr(rp, "run_notebook", fake_run)
    with pytest.raises(KeyboardInterrupt):
        rp.reproduce(only=["00", "01"], out=out, jobs=1)
    text = (out / "summary.md").read_text()
    assert "INTERRUPTED" in text and f"{calls[0]} (ok)" in text and calls[1] not in text and "all ok" not in text
    assert not (out / "summary.json").exists() and not (out / ".reproduce.lock").exists()
    assert not list(out.glob(".*.tmp"))


def test_an_interrupted_concurrent_run_names_what_finished_before_it(monkeypatch, tmp_path):
    first_done = threading.Event()

    def fake_run(source, out_dir, parameters, **kwargs):
        if source.stem.startswith("00"):
            first_done.set()
            return rp.NotebookRun(notebook=source.stem, source=source, executed=out_dir / "x.ipynb", html=None,
                                  summary=out_dir / "x.json", seconds=0.0, error=None)
        first_done.wait(10)
        time.sleep(0.2)                      # let the first notebook's thread record its end
        raise KeyboardInterrupt

    monkeypatch.setattr(rp, "run_notebook", fake_run)
    with pytest.raises(KeyboardInterrupt):
        rp.reproduce(only=["00", "01"], out=tmp_path, jobs=2)
    text = (tmp_path / "summary.md").read_text()
    assert "INTERRUPTED" in text and "00_quickstart (ok)" in text and "01_set_noise_pf" not in text
    assert not (tmp_path / "summary.json").exists() and not (tmp_path / ".reproduce.lock").exists()


def test_an_inproc_scheduler_is_refused_for_the_notebooks(tmp_path):
    """The notebooks run in kernels of their own: an in-process scheduler address cannot reach them."""
    path = NOTEBOOKS_DIR / "04_doppler_beacons.ipynb"
    with pytest.raises(ValueError, match="inproc:// address lives inside one Python process"):
        rp.resolve_parameters([path], text={"DASK_SCHEDULER": "inproc://10.0.0.5/123/1"})
    with pytest.raises(ValueError, match="inproc:// address lives inside one Python process"):
        rp.reproduce(only=["04"], out=tmp_path, scheduler="inproc://10.0.0.5/123/1")
