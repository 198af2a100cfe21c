"""Fixed inputs and outputs of every existing EKF configuration, for the golden test.

``python -m tests.golden.ekf_cases`` (from the repository root) writes ``ekf_golden.npz``
beside this file: every array of every case's :class:`~uwbwb.filters.ekf.KalmanRun` (priors,
posteriors, transitions, NIS, dof, status, gate rejections) and the platform they were computed
on. :mod:`tests.golden.test_ekf_golden` recomputes the cases and compares them with the file.

The inputs are synthetic (fixed seeds): a TDoA log with missing rows, reference changes and
NLOS outliers on some anchors, and a linear position-fix log with outliers. The cases cover
the configurations the package uses: the TDoA EKF with each motion model, in 2-D and 3-D,
ungated and with the anchor-dropping gate at several probabilities, ``min_tdoa`` and
``max_skipped`` release, a supplied prior that starts far off; and the generic EKF with no gate
and with the per-epoch χ² gate (with its ``max_gated`` release), plus an RTS smoothing.
"""

from __future__ import annotations

import hashlib
import platform
from pathlib import Path

import numpy as np

from uwbwb.filters.ekf import Ekf, KalmanRun, Linearisation, TdoaEkf
from uwbwb.filters.kalman import Gaussian
from uwbwb.models.motion import RandomForce, RandomJerk, RandomWalk
from uwbwb.models.tdoa import TdoaModel
from uwbwb.types import TdoaLog, pseudo_tdoa

GOLDEN = Path(__file__).with_name("ekf_golden.npz")
DIGEST = Path(__file__).with_name("ekf_golden.sha256")
FIELDS = ("x_prior", "P_prior", "x_post", "P_post", "F", "nis", "dof", "status", "n_rejected")
ANCHORS = np.array([[0.0, 0.0, 3.0], [30.0, 0.0, 0.5], [30.0, 30.0, 3.0], [0.0, 30.0, 0.5],
                    [15.0, -2.0, 2.0], [15.0, 32.0, 1.0], [-2.0, 15.0, 2.0], [32.0, 15.0, 1.5]])
IDS = tuple(f"a{i}" for i in range(8))


def fingerprint() -> str:
    """Where the numbers were computed (numpy version, machine, CPU model): a record in the file, not a
    condition of the comparison (:mod:`tests.golden` compares to a stated tolerance on any machine)."""
    cpu = ""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
        cpu = next((ln.split(":", 1)[1].strip() for ln in lines if ln.startswith("model name")), "")
    except OSError:
        pass
    return f"numpy {np.__version__} {platform.machine()} {platform.system()} {cpu}".strip()


def _tdoa_log(dim: int, *, seed: int) -> tuple[TdoaLog, np.ndarray]:
    rng = np.random.default_rng(seed)
    model = TdoaModel(ANCHORS, 0.1, dim=dim, z_m=1.0)
    t = np.arange(0, 12, 0.1)
    pos = np.column_stack([8 + 0.5 * t, 10 + 0.2 * t + np.sin(0.3 * t)] + ([1.0 + 0.02 * t] if dim == 3 else []))
    r = model.ranges(pos) + 0.1 * rng.standard_normal((t.size, 8))
    r[rng.random(r.shape) < 0.08] = np.nan
    r[30:33] = np.nan                                  # nothing measured
    hit = np.zeros(t.size, bool)
    hit[40::9] = True
    r[hit, 3] += 3.0                                   # NLOS bias on one anchor
    r[hit & (np.arange(t.size) % 18 == 4), 0] += 2.5   # ...and sometimes on the reference
    r[100, :] += np.array([0.0, 9.0, -7.0, 8.0, -9.0, 7.0, -8.0, 9.0])   # nothing consistent left
    refs = np.where(np.arange(t.size) < 70, 0, 5)
    d = np.full(r.shape, np.nan)
    ref = np.full(t.size, -1)
    for k in (0, 5):
        rows = refs == k
        d[rows], ref[rows] = pseudo_tdoa(r[rows], k)
    return TdoaLog(t, d, ref, IDS), pos


class _PositionFix:
    """Linear model: the position of the state measured with noise ``var_m2`` (NaN = missing)."""

    def __init__(self, motion, var_m2: float = 0.09):
        self.H, self.var = motion.H_pos, var_m2

    def linearise(self, x, z):
        z = np.asarray(z, float)
        if not np.all(np.isfinite(z)):
            return None
        return Linearisation(z, self.H @ x, self.H, self.var * np.eye(z.size))


def _fix_log(*, seed: int):
    rng = np.random.default_rng(seed)
    motion = RandomForce(psd_m2ps3=0.5, dim=2)
    t = np.arange(120) * 0.1
    x = motion.sample_path(motion.initial_state([0.0, 0.0], [1.0, 0.5]), t, rng=rng)
    z = motion.position(x) + 0.3 * rng.standard_normal((t.size, 2))
    z[20:23] = np.nan
    z[60::25] += 4.0                                   # outliers
    z[90:94] += 8.0                                  # a run of them: the gate releases
    P0 = motion.initial_covariance(1.0, 1.0)
    return motion, t, z, Gaussian(x[0] + np.array([0.3, -0.2, 0.1, 0.0]), P0)


def runs() -> dict[str, KalmanRun]:
    """Every case, by name."""
    out = {}
    for dim in (2, 3):
        log, pos = _tdoa_log(dim, seed=11 + dim)
        model = TdoaModel(ANCHORS, 0.1, dim=dim, z_m=1.0)
        motions = {"RW": RandomWalk(0.3, dim=dim), "RF": RandomForce(0.2, dim=dim), "RJ": RandomJerk(0.1, dim=dim)}
        for name, motion in motions.items():
            if dim == 3 and name == "RJ":
                continue
            out[f"tdoa{dim}d-{name}-default"] = TdoaEkf(motion, model).run(log)
            out[f"tdoa{dim}d-{name}-nogate"] = TdoaEkf(motion, model, gate_prob=None).run(log)
        rf = motions["RF"]
        out[f"tdoa{dim}d-RF-p0.999"] = TdoaEkf(rf, model, gate_prob=0.999).run(log)
        out[f"tdoa{dim}d-RF-p0.99-min3-skip3"] = TdoaEkf(rf, model, gate_prob=0.99, min_tdoa=3, max_skipped=3).run(log)
        out[f"tdoa{dim}d-RF-sigmas"] = TdoaEkf(rf, model, init_pos_sigma_m=0.5, init_vel_sigma_mps=0.1,
                                               init_acc_sigma_mps2=0.05).run(log, name="custom")
        ekf = TdoaEkf(RandomWalk(1e-4, dim=dim), model, gate_prob=0.99, max_skipped=4)
        x0 = ekf.init(pos[0] + 6.0)
        out[f"tdoa{dim}d-RW-offprior-skip4"] = ekf.run(log, x0=Gaussian(x0.x, 0.01 * x0.P))
    out["tdoa2d-RF-default-rts"] = out["tdoa2d-RF-default"].smooth()
    motion, t, z, x0 = _fix_log(seed=5)
    fix = _PositionFix(motion)
    for label, kw in (("nogate", dict(gate_prob=None)), ("default", {}),
                      ("p0.9-max2", dict(gate_prob=0.9, max_gated=2)), ("p0.999-max0", dict(gate_prob=0.999, max_gated=0))):
        out[f"fix-{label}"] = Ekf(motion, fix, pos_index=(0, 1), vel_index=(2, 3), **kw).run(t, z, x0, start=2)
    out["fix-nogate-rts"] = out["fix-nogate"].smooth()
    return out


def arrays(cases: dict[str, KalmanRun]) -> dict[str, np.ndarray]:
    """The flat ``{"<case>/<field>": array}`` dictionary stored in the golden file."""
    return {f"{name}/{f}": np.asarray(getattr(run, f)) for name, run in cases.items() for f in FIELDS}


def digest(flat: dict[str, np.ndarray]) -> str:
    """SHA-256 over every array's name, dtype, shape and bytes, in name order."""
    h = hashlib.sha256()
    for key in sorted(flat):
        a = np.ascontiguousarray(flat[key])
        h.update(f"{key}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def write(path: Path = GOLDEN) -> None:
    flat = arrays(runs())
    np.savez_compressed(path, __fingerprint__=np.array(fingerprint()), **flat)
    DIGEST.write_text(f"{digest(flat)}  {fingerprint()}\n")


if __name__ == "__main__":
    write()
    print(f"wrote {GOLDEN} ({fingerprint()})")
