"""Bit for bit where it is true: every golden case computed again, in a second process on this machine,
gives the same bytes as this process's run. (Against the golden file, written on another machine, the
comparison is to the tolerance of :mod:`tests.golden`; the tests below show that rule can fail.)"""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from numpy._core._multiarray_umath import __cpu_dispatch__

from tests.golden import RTOL, mismatch

ROOT = Path(__file__).resolve().parents[2]
SECOND_RUN = """
import sys, numpy as np
from tests.golden import computed, doppler_cases, ekf_cases, eskf_cases
flat = {f"{m.__name__}|{k}": v for m in (ekf_cases, eskf_cases, doppler_cases) for k, v in computed(m).items()}
np.savez(sys.argv[1], **flat)
"""


def test_a_second_run_on_this_machine_gives_the_same_bytes(tmp_path, ekf_recomputed, eskf_recomputed,
                                                            doppler_recomputed):
    out = tmp_path / "second.npz"
    subprocess.run([sys.executable, "-c", SECOND_RUN, str(out)], cwd=ROOT, check=True)
    second = np.load(out)
    first = {**{f"tests.golden.ekf_cases|{k}": v for k, v in ekf_recomputed.items()},
             **{f"tests.golden.eskf_cases|{k}": v for k, v in eskf_recomputed.items()},
             **{f"tests.golden.doppler_cases|{k}": v for k, v in doppler_recomputed.items()}}
    assert sorted(second.files) == sorted(first)
    differ = [k for k in sorted(first) if np.asarray(first[k]).tobytes() != second[k].tobytes()
              or np.asarray(first[k]).dtype != second[k].dtype]
    assert not differ, f"{len(differ)} arrays differ between two runs on one machine: {differ[:5]}"


def test_the_cross_machine_rule_accepts_rounding_and_rejects_more():
    want = np.array([[1.0, -2.0, np.nan], [3e-3, 0.0, 4.0], [0.5, 1e-3, 1.0]])      # epochs x components
    assert mismatch(want.copy(), want) is None
    assert mismatch(want + 0.5 * RTOL * np.array([1.0, 2.0, 4.0]), want) is None   # within each component's scale
    assert mismatch(np.nextafter(want, np.inf), want) is None             # one ULP everywhere
    assert "differs at" in mismatch(want + 2 * RTOL * 4.0, want)
    # a small component keeps its own scale: a change far below the array's largest element still fails
    small = np.array([[1e3, 2.5e-7], [2e3, 2.0e-7]])
    assert "differs at (0, 1)" in mismatch(small * np.array([1.0, 1.44]), small)
    assert "NaN" in mismatch(np.where(np.isnan(want), 0.0, want), want)
    assert mismatch(want.astype(np.float32), want) is not None
    status = np.array([0, 1, 2, 2])
    assert mismatch(status.copy(), status) is None
    assert mismatch(status + np.array([0, 0, 0, 1]), status) is not None  # integers: exactly


OTHER_CPU = """
import sys, pytest
from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
assert not any(__cpu_features__.get(f) for f in __cpu_dispatch__), "NumPy's optional SIMD paths are still on"
sys.exit(pytest.main(["-q", "-p", "no:cacheprovider", *sys.argv[1:]]))
"""


def test_goldens_and_twins_hold_with_simd_off_and_the_oldest_blas_kernel():
    """Closer to what an older CPU computes, as far as one machine can show it: NumPy's optional SIMD
    paths switched off (``NPY_DISABLE_CPU_FEATURES``) and OpenBLAS pinned to its oldest x86-64 kernel
    (``OPENBLAS_CORETYPE=Prescott``); the golden and twin comparisons pass there as they do here."""
    env = dict(os.environ, NPY_DISABLE_CPU_FEATURES=" ".join(__cpu_dispatch__), OPENBLAS_CORETYPE="Prescott")
    files = [str(p.relative_to(ROOT)) for p in sorted(Path(__file__).parent.glob("test_*_golden.py"))]
    done = subprocess.run([sys.executable, "-c", OTHER_CPU, *files, "tests/test_kernel_twins.py"], cwd=ROOT,
                          env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
