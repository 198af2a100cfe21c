"""The two installs: environment.txt (the workbench: lab, class, reproduce) is enough for every module of the
package, and environment-test.txt adds only the test, browser and Dask tools on top of it."""

from __future__ import annotations

import ast
import importlib.metadata as md
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: What only environment-test.txt brings (import names; cloudpickle comes with dask).
TEST_ONLY = ("pytest", "xdist", "hypothesis", "playwright", "dask", "distributed", "bokeh", "cloudpickle")


def _norm(name: str) -> str:
    return name.lower().replace("_", "-").replace(".", "-")


def _pins(path: Path) -> dict[str, str]:
    pins = {}
    for line in path.read_text().splitlines():
        line = line.strip()
        if line and not line.startswith(("#", "-r")):
            name, _, version = line.partition("==")
            assert version, f"{path.name}: '{line}' is not pinned as name==version"
            pins[_norm(name)] = version
    return pins


def test_the_test_lock_builds_on_the_workbench_lock_without_repeating_it():
    light, test = _pins(ROOT / "environment.txt"), _pins(ROOT / "environment-test.txt")
    assert (ROOT / "environment-test.txt").read_text().count("-r environment.txt") == 1
    assert not set(light) & set(test), f"pinned in both: {sorted(set(light) & set(test))}"
    assert {"pytest", "playwright", "dask", "distributed"} <= set(test)
    assert not {"pytest", "playwright", "dask", "distributed", "bokeh", "hypothesis"} & set(light)


def _third_party_imports() -> set[str]:
    """Top-level names the package imports (at module level or inside functions) that are not its own or stdlib."""
    names = set()
    for path in (ROOT / "uwbwb").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split(".")[0])
    return {n for n in names if n != "uwbwb" and n not in sys.stdlib_module_names}


def test_every_package_the_workbench_imports_is_pinned_in_the_workbench_lock():
    light = _pins(ROOT / "environment.txt")
    dists = md.packages_distributions()
    missing = {}
    for name in sorted(_third_party_imports() - set(TEST_ONLY)):
        owners = {_norm(d) for d in dists.get(name, [])}
        if not owners & set(light):
            missing[name] = sorted(owners) or "not installed"
    assert not missing, f"imported by uwbwb but not pinned in environment.txt: {missing}"


def test_every_module_imports_without_the_test_tools():
    """Import every module of uwbwb with the test-only packages made unimportable: the workbench install works."""
    code = textwrap.dedent(f"""
        import importlib, pkgutil, sys
        class Block:
            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] in {TEST_ONLY!r}:
                    raise ImportError(f"{{name}} is a test-only package")
        sys.meta_path.insert(0, Block())
        import uwbwb
        for m in pkgutil.walk_packages(uwbwb.__path__, "uwbwb."):
            if not m.name.endswith("__main__"):
                importlib.import_module(m.name)
        print("imported", len(sys.modules))
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("imported")
