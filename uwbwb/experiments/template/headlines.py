"""The template's summary rows, declared as data, and its checks (both read from :func:`.facts.facts`).

Each :class:`~uwbwb.metrics.Headline` names the quantity, its unit, its kind (*reproduced*: came out of a method;
*target*: a simulator setting chosen to hit it; *input*: taken from the paper) and the paper's value
where one is comparable. :func:`checks` returns what fails (empty: everything holds); each check is
one a broken method or a broken comparison would fail (tests/experiments/test_template.py doctors a
result for each).
"""

from __future__ import annotations

from .facts import facts
from .study import METHODS, Results
from ...metrics import Headline, interval_text

__all__ = ["HEADLINES", "PAPER", "checks"]

#: What the paper states (a copied package puts its paper's printed values here). The template's
#: "paper" states the range noise the simulator is given, so that row is an *input*.
PAPER = {"sigma_range_m": 0.10}


HEADLINES: tuple[Headline, ...] = (
    *(Headline(f"RMSE {m}, common epochs", "cm", "reproduced", lambda f, m=m: 100 * f[f"rmse_m[{m}]"])
      for m in METHODS),
    *(Headline(f"coverage {m}", "%", "reproduced", lambda f, m=m: 100 * f[f"coverage[{m}]"]) for m in METHODS),
    Headline("ΔRMSE EKF-RF − LS, common epochs", "cm", "reproduced", lambda f: 100 * f["diff_m"]),
    Headline("mean NIS/dof EKF-RF", "", "reproduced", lambda f: f["nis_per_dof"]),
    Headline("range noise σ (simulator setting)", "cm", "input", lambda f: 100 * f["sigma_range_m"],
             100 * PAPER["sigma_range_m"]),
)


#: Smallest coverage of either method (FAST, full).
MIN_COVERAGE = (0.90, 0.98)
#: Largest LS RMSE as a multiple of the range σ (FAST, full): 4 corner anchors give a GDOP near 1.
LS_RMSE_PER_SIGMA = (3.0, 2.0)


def checks(res: Results, fast: bool) -> list[str]:
    """What must hold (looser under FAST); returns the failures, empty when all hold."""
    f = facts(res)
    i = 0 if fast else 1
    fail = []
    for m in METHODS:
        if not f[f"coverage[{m}]"] >= MIN_COVERAGE[i]:
            fail.append(f"{m} coverage {f[f'coverage[{m}]'] * 100:.0f} % of the epochs, "
                        f"below {MIN_COVERAGE[i] * 100:.0f} %")
    limit = LS_RMSE_PER_SIGMA[i] * f["sigma_range_m"]
    if not f["rmse_m[LS]"] <= limit:
        fail.append(f"LS RMSE {f['rmse_m[LS]']:.3f} m above {limit:.3f} m ({LS_RMSE_PER_SIGMA[i]:g} range σ)")
    if f["nis_verdict"] != "consistent":
        fail.append(f"EKF-RF mean NIS/dof {f['nis_per_dof']:.2f} outside the consistent band")
    if f["verdict"] != "better":
        fail.append(f"the EKF must beat LS on common epochs (ΔRMSE interval "
                    f"{interval_text(f['lo_m'], f['hi_m'], '+.3f')} m: {f['verdict']})")
    return fail
