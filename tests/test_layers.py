"""The import-layer contract of the package, and every sub-module reachable as ``uw.<name>``.

Layers, lowest first; a module may import from its own unit and from lower layers only. Units
in one layer are independent (none imports another). Imports inside functions may not cross
units at all: a dependency is declared at the top of the module, where it can be seen.

The order is the one the tree has (derived from its imports, issue 19): containers below the
models, the models below geometry (its range functions are the TWR model's) and below the
estimators and simulators, data access above them (a stand-in is
built from the simulators), presentation (plotting, widgets) above the data, the scoreboard (a
harness any experiment may use) above the core, one experiment package per notebook above it,
and the tooling (parameter typing, reproduce, CLI) last.

:data:`DEBT` lists the violations the tree had when the contract was introduced, each with the
issue that removes it. A *new* violation fails; so does a debt entry that no longer occurs
(delete it: the contract only tightens).
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "uwbwb"

#: Layers, lowest first. Each is a tuple of independent units (top-level modules or packages).
LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors", "validate", "parallel"),
    ("types",),
    ("models",),
    ("geometry", "metrics"),
    ("bounds", "calibration", "sampling", "sim"),
    ("filters",),
    ("datasets",),
    ("plotting", "widgets"),
    ("scoreboard",),
    ("experiments",),
    ("notebook_params",),
    ("reproduce",),
    ("classroom",),
    ("cli",),
    ("__main__",),
)

#: Known violations: (importing module, imported unit, "upward" | "sibling" | "local") -> issue.
DEBT: dict[tuple[str, str, str], str] = {
}

RANK = {unit: i for i, layer in enumerate(LAYERS) for unit in layer}


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _units() -> set[str]:
    return {p.stem if p.is_file() else p.name for p in PACKAGE.iterdir()
            if (p.suffix == ".py" and p.stem != "__init__") or (p.is_dir() and (p / "__init__.py").is_file())}


def _unit(module: str) -> str | None:
    """The top-level unit of ``uwbwb.<unit>...``; None for the root package itself."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def _imports(module: str, path: Path):
    """``(target module, inside a function)`` of every ``uwbwb`` import of a file."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    local = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            local |= {id(n) for n in ast.walk(node) if isinstance(n, (ast.Import, ast.ImportFrom))}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "uwbwb":
                    yield alias.name, id(node) in local
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "uwbwb":
                continue
            if target == "uwbwb":           # `from .. import x`: x is a unit, or a name of the root package
                units = _units()
                for alias in node.names:
                    yield (f"uwbwb.{alias.name}" if alias.name in units else "uwbwb"), id(node) in local
            else:
                yield target, id(node) in local


def violations() -> set[tuple[str, str, str]]:
    found = set()
    for module, path in _modules().items():
        src = _unit(module)
        if src is None:
            continue
        for target, in_function in _imports(module, path):
            dst = _unit(target)
            if dst is None or dst == src:
                continue
            if RANK[dst] > RANK[src]:
                found.add((module, dst, "upward"))
            elif RANK[dst] == RANK[src]:
                found.add((module, dst, "sibling"))
            if in_function:
                found.add((module, dst, "local"))
    return found


def test_every_unit_has_a_layer():
    missing = sorted(_units() - set(RANK))
    assert not missing, f"put {missing} into a layer of tests/test_layers.py (LAYERS)"


def test_no_new_layer_violations():
    new = sorted(violations() - set(DEBT))
    assert not new, ("imports that break the layer contract (upward, between independent units, or inside a "
                     "function across units):\n" + "\n".join(f"  {m} -> uwbwb.{u} ({k})" for m, u, k in new))


def test_the_debt_list_only_shrinks():
    gone = sorted(set(DEBT) - violations())
    assert not gone, "these violations are gone; delete them from DEBT:\n" + "\n".join(map(str, gone))


def test_the_checker_sees_violations(tmp_path, monkeypatch):
    # the contract test would pass vacuously if the scan saw no imports
    bad = tmp_path / "uwbwb"
    (bad / "models").mkdir(parents=True)
    (bad / "__init__.py").write_text("")
    (bad / "types.py").write_text("")
    (bad / "filters.py").write_text("")
    (bad / "models" / "__init__.py").write_text("from ..types import x\n")
    (bad / "models" / "m.py").write_text("from .. import filters\n\ndef f():\n    from ..types import y\n")
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", bad)
    assert violations() == {("uwbwb.models.m", "filters", "upward"), ("uwbwb.models.m", "types", "local")}


def test_every_submodule_is_reachable_as_an_attribute_in_a_fresh_interpreter():
    units = sorted(_units() - {"__main__"})
    code = ("import uwbwb as uw\n"
            f"names = {units!r}\n"
            "missing = [n for n in names if not hasattr(uw, n)]\n"
            "assert not missing, missing\n"
            "assert set(names) <= set(dir(uw)), sorted(set(names) - set(dir(uw)))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]


@pytest.mark.parametrize("name", ["nonexistent", "__main__"])
def test_other_attributes_are_still_attribute_errors(name):
    import uwbwb as uw

    with pytest.raises(AttributeError):
        getattr(uw, name)


#: The most lines a module of the package may have (issue 19); a declared kernel longer than that would be
#: listed in :data:`LONG_KERNELS` with the reason (none is today).
MAX_MODULE_LINES = 600
LONG_KERNELS: dict[str, str] = {}


def _too_long(package: Path) -> dict[str, int]:
    out = {}
    for path in sorted(package.rglob("*.py")):
        name = path.relative_to(package).as_posix()
        n = len(path.read_text(encoding="utf-8").splitlines())
        if n > MAX_MODULE_LINES and name not in LONG_KERNELS:
            out[name] = n
    return out


def test_no_module_is_longer_than_the_limit():
    long = _too_long(PACKAGE)
    assert not long, (f"modules over {MAX_MODULE_LINES} lines (split them by responsibility): "
                      + ", ".join(f"{k} ({v})" for k, v in long.items()))


def test_the_length_check_sees_a_long_module(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "long.py").write_text("x = 1\n" * (MAX_MODULE_LINES + 1))
    (tmp_path / "short.py").write_text("x = 1\n" * MAX_MODULE_LINES)
    assert _too_long(tmp_path) == {"sub/long.py": MAX_MODULE_LINES + 1}


#: An experiment's ``study.py`` is orchestration only (issue 19): at most this many lines.
MAX_STUDY_LINES = 400


def test_every_experiment_study_is_orchestration_sized():
    long = {p.parent.name: n for p in sorted((PACKAGE / "experiments").glob("*/study.py"))
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_STUDY_LINES}
    assert not long, f"experiments whose study.py is over {MAX_STUDY_LINES} lines (move analysis out): {long}"
