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
    ("plotting", "widgets", "coding"),
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


def _defined(tree: ast.Module) -> set[str]:
    """Names a module binds at its top level other than by importing them."""
    out = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            for target in (node.targets if isinstance(node, ast.Assign) else [node.target]):
                out |= {n.id for n in ast.walk(target) if isinstance(n, ast.Name)}
    return out


def _top_imports(module: str, path: Path, tree: ast.Module):
    """``(node, resolved module, alias)`` of every top-level ``from … import`` of the package."""
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.module != "__future__":
            if node.level:
                parts = package.split(".")
                target = ".".join(parts[: len(parts) - node.level + 1] + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            for alias in node.names:
                yield node, target, alias


def _parsed(package: Path | None) -> tuple[dict[str, Path], dict[str, ast.Module]]:
    """The modules of ``package`` (default :data:`PACKAGE`) and their syntax trees."""
    global PACKAGE
    saved, PACKAGE = PACKAGE, package or PACKAGE
    try:
        modules = _modules()
    finally:
        PACKAGE = saved
    return modules, {m: ast.parse(p.read_text(encoding="utf-8"), str(p)) for m, p in modules.items()}


def re_exports(package: Path | None = None) -> list[str]:
    """Imports that only pass a name on, and imports of a name from a module that does not define it.

    A module other than a package's ``__init__`` uses every name it imports (an import only listed in
    ``__all__`` is a re-export) and lists in ``__all__`` only names it defines; and nobody imports a name
    from a plain module that got it by importing. A package's ``__init__`` is its public face and may
    gather names, from the module that defines each.
    """
    modules, trees = _parsed(package)
    found = []
    for module, tree in trees.items():
        path = modules[module]
        mine = _defined(tree)
        if path.name != "__init__.py":
            exported = [n for node in tree.body if isinstance(node, ast.Assign)
                        and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets)
                        for n in ast.walk(node.value) if isinstance(n, ast.Constant)]
            listed = {id(n) for n in exported}
            used = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
            text = " ".join(n.value for n in ast.walk(tree)                    # string annotations, doctests
                            if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in listed)
            for node, _, alias in _top_imports(module, path, tree):
                name = alias.asname or alias.name
                if name not in used and name not in text:
                    found.append(f"{module}: imports {name} and does not use it (a re-export)")
            found += [f"{module}: __all__ lists {n.value}, which it does not define" for n in exported
                      if n.value not in mine]
        for node, target, alias in _top_imports(module, path, tree):
            source = modules.get(target)
            if (source is not None and source.name != "__init__.py" and f"{target}.{alias.name}" not in modules
                    and alias.name not in _defined(trees[target])):
                found.append(f"{module}: imports {alias.name} from {target}, which does not define it")
    return sorted(found)


def import_circles(package: Path | None = None) -> list[list[str]]:
    """Groups of modules that import each other at their top level (strongly connected components)."""
    modules, trees = _parsed(package)
    # imports run when the module loads: its top level (not functions, not `if TYPE_CHECKING:` blocks)
    graph = {m: {f"{t}.{a.name}" if f"{t}.{a.name}" in modules else t
                 for _, t, a in _top_imports(m, modules[m], tree)} - {m} for m, tree in trees.items()}
    # a package's __init__ and the modules it gathers are one unit: edges into an ancestor package do not count
    graph = {m: {t for t in ts if t in modules and not m.startswith(t + ".")} for m, ts in graph.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles = []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                circles.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return circles


def test_no_module_passes_names_on():
    found = re_exports()
    assert not found, "import each name from the module that defines it:\n" + "\n".join(found)


def test_no_import_circle():
    circles = import_circles()
    assert not circles, f"modules that import each other (one of them holds what both need): {circles}"


def test_the_structure_checks_see_re_exports_and_circles(tmp_path):
    pkg = tmp_path / "uwbwb"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("from .a import f\n")                      # a package's face: allowed
    (pkg / "a.py").write_text("from .b import g\n\n__all__ = ['f', 'g']\n\ndef f():\n    return g()\n")
    (pkg / "b.py").write_text("from .a import f\nfrom .c import h\n\ndef g():\n    return f()\n")
    (pkg / "c.py").write_text("def h():\n    return 1\n")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "d.py").write_text("from ..a import g\n\ndef k():\n    return g()\n")
    assert re_exports(pkg) == ["uwbwb.a: __all__ lists g, which it does not define",
                               "uwbwb.b: imports h and does not use it (a re-export)",
                               "uwbwb.sub.d: imports g from uwbwb.a, which does not define it"]
    assert import_circles(pkg) == [["uwbwb.a", "uwbwb.b"]]
