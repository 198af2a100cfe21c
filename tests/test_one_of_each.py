"""One of each: the package's one block-bootstrap interval rule, its one interval over seeds, its one interval →
verdict rule, its one thinning rule and its one interval formatter are defined once.

A second definition elsewhere — a block length, a block cut, a block bootstrap, a comparison of an interval's
ends with a null value, a thinning function — would let two notebooks give two verdicts on one comparison; these
tests read every module's source and fail on it.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import uwbwb

PACKAGE = Path(uwbwb.__file__).resolve().parent


def _functions() -> list[tuple[str, str]]:
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        rel = path.relative_to(PACKAGE).as_posix()
        out += [(rel, node.name) for node in ast.walk(tree) if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))]
    return out


def test_the_block_bootstrap_is_defined_once_in_metrics():
    block = re.compile(r"block_(ids|length|bootstrap)|bootstrap_(ratio|difference)|ratio_interval|block_length_s")
    found = sorted((m, f) for m, f in _functions() if block.search(f))
    assert found == [("metrics/errors.py", "block_bootstrap_difference"), ("metrics/errors.py", "block_ids"),
                     ("metrics/errors.py", "block_length")], found


def test_the_thinning_rule_is_recording_decimate_alone():
    thin = re.compile(r"^(thin|decimate|downsample|subsample)$|^_?thin_")
    found = sorted((m, f) for m, f in _functions() if thin.search(f))
    assert found == [("types/recording.py", "decimate")], found


#: Names an interval's ends go by in the package (variables, dict keys, attributes).
_ENDS = re.compile(r"^(lo|hi)(_m|_mm|_cm)?$|^ratio_(lo|hi)$")


def _end(node: ast.AST) -> bool:
    if isinstance(node, ast.Name):
        return bool(_ENDS.match(node.id))
    if isinstance(node, ast.Attribute):
        return bool(_ENDS.match(node.attr))
    if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) and isinstance(node.slice.value, str):
        return bool(_ENDS.match(node.slice.value))
    return False


def interval_comparisons(package: Path = PACKAGE) -> list[tuple[str, int]]:
    """``(module, line)`` of every ``<``, ``>``, ``<=``, ``>=`` between an interval's end and something else, where
    verdicts are made: in ``facts.py`` and ``verdicts.py`` modules and in any function named for a verdict."""
    out = []
    for path in sorted(package.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        scopes = ([tree] if path.name in ("facts.py", "verdicts.py") else
                  [f for f in ast.walk(tree) if isinstance(f, ast.FunctionDef) and "verdict" in f.name])
        for node in {id(n): n for scope in scopes for n in ast.walk(scope)}.values():
            if (isinstance(node, ast.Compare) and any(isinstance(op, (ast.Lt, ast.Gt, ast.LtE, ast.GtE)) for op in node.ops)
                    and any(_end(x) for x in [node.left, *node.comparators])):
                out.append((path.relative_to(package).as_posix(), node.lineno))
    return out


def test_intervals_become_verdicts_through_metrics_interval_side_alone():
    found = [(m, line) for m, line in interval_comparisons() if m != "metrics/errors.py"]
    assert not found, f"decide with uwbwb.metrics.interval_side (name its outcomes in a dict), not here: {found}"


def test_the_interval_check_sees_a_comparison(tmp_path):
    (tmp_path / "facts.py").write_text("def f(r, lo_m, x):\n    return 'a' if r['hi_m'] < 0 else lo_m > x\n")
    (tmp_path / "m.py").write_text("def my_verdict(lo, hi):\n    return lo > 1\n\ndef axis(lo, v):\n    return v < lo\n")
    (tmp_path / "ok.py").write_text("def g_verdict(lo, hi):\n    return lo == hi\n")
    assert sorted(interval_comparisons(tmp_path)) == [("facts.py", 2), ("facts.py", 2), ("m.py", 2)]


def test_the_interval_over_seeds_is_defined_once_in_metrics():
    """Student-t over independent seeds: one definition (metrics.seeds_interval), used by 03's seeds study and 05's
    ablation ratios; a second t quantile elsewhere would be a second copy of the rule."""
    found = sorted(p.relative_to(PACKAGE).as_posix() for p in PACKAGE.rglob("*.py")
                   if re.search(r"\bt\.ppf\(", p.read_text(encoding="utf-8")))
    assert found == ["metrics/errors.py"], found


def test_an_interval_is_written_as_text_once_in_metrics():
    """``"[lo, hi]"`` with both ends formatted: one definition (metrics.interval_text), so every table and figure
    writes an interval, and its absence, alike."""
    pattern = re.compile(r"\[\{[^\n]*?:[^\n]*?\}, \{[^\n]*?:[^\n]*?\}\]")     # f"[{lo:.2f}, {hi:.2f}]"
    found = sorted(p.relative_to(PACKAGE).as_posix() for p in PACKAGE.rglob("*.py")
                   if pattern.search(p.read_text(encoding="utf-8")))
    assert found == ["metrics/summary.py"], found
