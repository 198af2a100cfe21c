"""One of each: the package's one block-bootstrap interval rule and its one thinning rule are defined once.

A second definition elsewhere — a block length, a block cut, a block bootstrap, a thinning function — would let
two notebooks give two verdicts on one comparison; these tests read every module's source and fail on it.
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
