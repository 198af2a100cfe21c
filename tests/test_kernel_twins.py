"""Every compiled or hand-vectorised kernel equals its declared Python definition
(:mod:`uwbwb.filters.twins`), and no compiled kernel is left without a twin."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import numpy as np
import pytest
from numba.core.registry import CPUDispatcher

from uwbwb.filters.twins import BIT, TWINS, Tol

PACKAGE = Path(__file__).resolve().parents[1] / "uwbwb"


@pytest.mark.parametrize("name", list(TWINS))
def test_kernel_equals_its_definition(name):
    twin = TWINS[name]
    problems = twin.mismatches()
    assert not problems, "\n".join(problems)


def _is_jit(node) -> bool:
    """``numba.njit``, ``njit``, ``numba.jit`` or a call of one of them (``numba.njit(cache=True)``)."""
    target = node.func if isinstance(node, ast.Call) else node
    return ast.unparse(target).split(".")[-1] in ("njit", "jit")


def _compiled_in_source() -> set[str]:
    """``uwbwb.<module>.<name>`` of every compiled function: decorated with ``numba.njit``/``numba.jit``,
    or assigned as ``name = numba.njit(...)(python_function)``."""
    found = set()
    for path in sorted(PACKAGE.rglob("*.py")):
        module = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef) and any(_is_jit(d) for d in node.decorator_list):
                found.add(f"{module}.{node.name}")
            elif (isinstance(node, ast.Assign) and isinstance(node.value, ast.Call)
                  and _is_jit(node.value.func)):
                found |= {f"{module}.{t.id}" for t in node.targets if isinstance(t, ast.Name)}
    return found


def test_every_compiled_kernel_has_a_twin():
    compiled = _compiled_in_source()
    assert len(compiled) >= 10                      # the scan sees the kernels (it is not vacuous)
    covered = {c for t in TWINS.values() for c in t.covers}
    missing = sorted(compiled - covered)
    assert not missing, f"compiled kernels without a declared twin in uwbwb/filters/twins.py: {missing}"


def test_every_covered_name_is_a_compiled_function():
    for twin in TWINS.values():
        for qual in twin.covers:
            module, attr = qual.rsplit(".", 1)
            obj = getattr(importlib.import_module(module), attr)
            assert isinstance(obj, CPUDispatcher), (twin.name, qual)


#: Twins of a whole filter run compared in ULP: the filter carries a rounding difference from epoch to epoch as it
#: carries a one-ulp change of its prior (the TDoA EKF's Python loop moves by up to 750 ULP for one; see its twin).
RUNS_IN_ULPS = ("ekf.TdoaEkf.run[", "ekf.RangeEkf.run[")


def test_every_twin_names_its_test_and_keeps_tight_tolerances():
    for twin in TWINS.values():
        assert twin.tolerance, twin.name
        assert twin.held_by.startswith("tests/") and "::" in twin.held_by, twin.name
        ulps = 2048 if twin.name.startswith(RUNS_IN_ULPS) else 64
        for key, tol in twin.tolerance.items():
            # the loosest exactness test in the suite: batched Gauss-Newton against scipy, per epoch
            assert isinstance(tol, Tol) and tol.rtol <= 1e-4 and tol.atol <= 1e-6 and tol.ulps <= ulps, \
                (twin.name, key, tol)


# ------------------------------------------------------------------ the comparison sees a difference
def test_a_one_ulp_change_fails_a_bit_for_bit_twin():
    twin = TWINS["ins._dcm_nb"]
    assert set(twin.tolerance.values()) == {BIT}
    fast, ref = twin.outputs()
    assert not twin.mismatches(fast, ref)
    fast["C"] = fast["C"].copy()
    fast["C"].flat[2] = np.nextafter(fast["C"].flat[2], np.inf)
    assert any("C" in m for m in twin.mismatches(fast, ref))


def test_an_ulps_tolerance_scales_with_the_outputs_largest_element():
    twin = TWINS["ins.propagate"]
    fast, ref = twin.outputs()
    ulps = twin.tolerance["Phi"].ulps
    unit = np.finfo(float).eps * np.abs(ref["Phi"]).max()
    for step, fails in ((0.5 * ulps * unit, False), (4 * ulps * unit, True)):
        doctored = dict(fast, Phi=ref["Phi"] + step)
        assert any("Phi" in m for m in twin.mismatches(doctored, ref)) == fails, step


def test_a_change_beyond_the_tolerance_fails_and_one_within_passes():
    twin = TWINS["kalman.update_sequential[correlated R]"]
    fast, ref = twin.outputs()
    atol = twin.tolerance["x"].atol
    for step, fails in ((0.5 * atol, False), (10 * atol, True)):
        doctored = dict(fast, x=fast["x"] + step)
        assert bool(twin.mismatches(doctored, ref)) == fails, step


def test_a_vacuous_comparison_fails():
    twin = TWINS["setnoise.pf_sweep[systematic]"]
    fast, ref = twin.outputs()
    assert not twin.mismatches(fast, ref)
    none = dict(ref, n_resampled=np.int64(0))
    assert any("vacuous" in m for m in twin.mismatches(dict(fast, n_resampled=np.int64(0)), none))


def test_missing_or_extra_outputs_fail():
    twin = TWINS["ins._dcm_nb"]
    fast, ref = twin.outputs()
    assert twin.mismatches({}, ref)
    assert twin.mismatches(dict(fast, extra=np.zeros(1)), dict(ref, extra=np.zeros(1)))
