"""Fixed inputs and outputs of the Doppler filters, for the golden test.

``python -m tests.golden.doppler_cases`` (from the repository root) writes ``doppler_golden.npz``
beside this file: every array of every case's :class:`~uwbwb.filters.doppler.DopplerPf` run
(estimates, ESS, particle covariances, restarts, tempered share, rows used) and
:class:`~uwbwb.filters.doppler.ScaatMhEkf` run (estimates, covariances, status, hypotheses,
assignments), and the platform they were computed on. :mod:`tests.golden.test_doppler_golden`
recomputes the cases and compares them with the file.

The input is one synthetic recording (fixed seed) of the reconstructed lab: the rectangle walked
for 9 s with timing jitter, 5 % missed chirps and 1 spurious detection per second, assigned by the
front end, with exact clock pseudo-ranges. The PF cases cover the default filter, two blocks of
runs, pseudo-ranges (where tempering acts), no tempering, ambiguous chirps, no outlier term, no
roughening and resampling at every chirp; the MH-EKF cases the default, pseudo-ranges, a high
clutter rate and a small hypothesis budget.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from tests.golden.ekf_cases import digest, fingerprint
from uwbwb.filters import doppler as fd
from uwbwb.filters.kalman import Gaussian
from uwbwb.models import doppler as dm
from uwbwb.sim import chirps as sc

GOLDEN = Path(__file__).with_name("doppler_golden.npz")
DIGEST = Path(__file__).with_name("doppler_golden.sha256")
PF_FIELDS = ("t_s", "pos_m", "vel_mps", "ess", "pos_cov_m2", "restarts", "tempered", "rows")
MH_FIELDS = ("t_s", "pos_m", "vel_mps", "pos_cov_m2", "status", "n_hypotheses", "beacon")
PF_CASES = {
    "default": ({}, {}),
    "ranges": ({}, {"ranges": True}),
    "ranges-notemper": ({"temper_ess": 0.0}, {"ranges": True}),
    "ambiguous": ({"use_ambiguous": True}, {}),
    "no-outlier-no-roughening": ({"outlier_prob": 0.0, "roughening": 0.0}, {}),
    "resample-always": ({"resample_threshold": 1.0}, {"ranges": True}),
}
MH_CASES = {
    "default": ({}, {}),
    "ranges": ({}, {"ranges": True}),
    "clutter": ({"spurious_rate_hz": 5.0, "p_detect": 0.8}, {}),
    "two-hypotheses": ({"max_hypotheses": 2, "prune_ratio": 0.1}, {}),
}


def recording():
    """The lab model, the chirp log, its pseudo-ranges and the truth."""
    lab = dm.DopplerModel.for_layout(dm.lab_layout())
    track, _ = sc.rectangle_track()
    rec = sc.simulate_chirps(lab, track, 9.0, rng=np.random.default_rng(3), p_miss=0.05, spurious_rate_hz=1.0)
    log = fd.assign_chirps(rec.t_s, lab)
    return lab, log, fd.clock_pseudo_ranges(log, lab, rec.phase_s), rec


def pf_arrays(runs) -> dict[str, np.ndarray]:
    """The stored arrays of one :meth:`DopplerPf.run` result."""
    return {"t_s": runs.t_s, "pos_m": runs.pos_m, "vel_mps": runs.vel_mps, "ess": runs.ess,
            "pos_cov_m2": runs.pos_cov_m2, "restarts": runs.meta["restarts"],
            "tempered": runs.meta["tempered"], "rows": runs.meta["rows"]}


def mh_arrays(est) -> dict[str, np.ndarray]:
    """The stored arrays of one :meth:`ScaatMhEkf.run` result."""
    return {"t_s": est.t_s, "pos_m": est.pos_m, "vel_mps": est.vel_mps, "pos_cov_m2": est.pos_cov_m2,
            "status": est.status, "n_hypotheses": est.info["n_hypotheses"], "beacon": est.info["beacon"]}


def arrays() -> dict[str, np.ndarray]:
    """The flat ``{"<filter>-<case>/<field>": array}`` dictionary stored in the golden file."""
    lab, log, ranges, rec = recording()
    out = {}
    for name, (kw, opt) in PF_CASES.items():
        pf = fd.DopplerPf(lab, n_particles=300, **kw)
        runs = pf.run(log, n_runs=3, block_runs=2, rng=np.random.default_rng(17),
                      ranges_m=ranges if opt.get("ranges") else None)
        out.update({f"pf-{name}/{k}": np.asarray(v) for k, v in pf_arrays(runs).items()})
    x0 = np.concatenate([rec.truth.pos_m[0] + [0.3, -0.2, 0.1], rec.truth.vel_mps[0] + [0.1, -0.1, 0.0]])
    prior = Gaussian(x0, np.diag([0.4 ** 2] * 3 + [0.4 ** 2] * 3))
    model = replace(lab, sigma_model_mps=0.05)
    for name, (kw, opt) in MH_CASES.items():
        est = fd.ScaatMhEkf(model, **kw).run(log, prior, ranges_m=ranges if opt.get("ranges") else None)
        out.update({f"mh-{name}/{k}": np.asarray(v) for k, v in mh_arrays(est).items()})
    return out


def write(path: Path = GOLDEN) -> None:
    flat = arrays()
    np.savez_compressed(path, __fingerprint__=np.array(fingerprint()), **flat)
    DIGEST.write_text(f"{digest(flat)}  {fingerprint()}\n")


if __name__ == "__main__":
    write()
    print(f"wrote {GOLDEN} ({fingerprint()})")
