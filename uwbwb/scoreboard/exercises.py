"""Exercises of notebook 06 ("change X, predict Y") on the synthetic hall, where truth and noise are known.

Each function runs both settings with the same seeds (the same tracks; the noise drawn from the same
numbers, scaled) through :func:`.synthetic.monte_carlo` and returns a
:class:`uwbwb.widgets.ExerciseCheck`: the direction the student predicts, whether this run shows it,
and the numbers. The reasoning is the check's ``why``, shown
once the student has predicted; ``TEACHING.md`` gives one run's numbers.
"""

from __future__ import annotations

from dataclasses import replace

from .. import validate
from ..widgets import ExerciseCheck
from .estimators import CalibratedLs, TdoaEkfEstimator
from .synthetic import SyntheticConfig, own_bound_summary, monte_carlo

__all__ = ["lower_rate", "noisier_ranges"]


def _summary(config: SyntheticConfig, n_runs: int, seed: int, estimators):
    return own_bound_summary(monte_carlo(n_runs, config, seed=seed, estimators=estimators)).set_index("method")


def noisier_ranges(config: SyntheticConfig = SyntheticConfig(), *, factor: float = 2.0, n_runs: int = 3,
                   seed: int = 0) -> ExerciseCheck:
    """Exercise: multiply the range noise σ by ``factor``; predict the LS RMSE and its snapshot CRLB.

    The snapshot CRLB is σ times a geometry term, so it scales by exactly ``factor`` (a number shown, not
    the claim: it cannot do otherwise). The claim is about the error: the LS fix is efficient here, so on
    fresh tracks and noise (the noisier runs draw their own) its RMSE grows by ``factor`` within 20 %.

    Returns
    -------
    ExerciseCheck
        Numbers: LS RMSE and its bound (cm) before and after, and their ratios.
    """
    factor = validate.number("factor", factor, minimum=0, strict_minimum=True)
    n_runs = validate.integer("n_runs", n_runs, minimum=2)
    before = _summary(config, n_runs, seed, [CalibratedLs()]).loc["LS"]
    after = _summary(replace(config, sigma_m=config.sigma_m * factor), n_runs, seed + n_runs,
                     [CalibratedLs()]).loc["LS"]
    b_ratio, r_ratio = after.bound_m / before.bound_m, after.rmse_m / before.rmse_m
    holds = abs(r_ratio / factor - 1) < 0.2
    return ExerciseCheck(f"range σ ×{factor:g}: the LS RMSE grows ×{factor:g} (within 20 %)", holds,
                         {"RMSE before (cm)": 100 * before.rmse_m, "RMSE after (cm)": 100 * after.rmse_m,
                          "bound before (cm)": 100 * before.bound_m, "bound after (cm)": 100 * after.bound_m,
                          "bound ratio": b_ratio, "RMSE ratio": r_ratio},
                         (f"about ×{factor:g}", f"not about ×{factor:g}"),
                         "The snapshot CRLB is σ times a geometry term (the bound ratio is exactly the factor); an "
                         "efficient estimator's error follows its bound, so RMSE / bound stays where it was.")


def lower_rate(config: SyntheticConfig = SyntheticConfig(), *, rate_hz: float = 4.0, n_runs: int = 3,
               seed: int = 0) -> ExerciseCheck:
    """Exercise: lower the epoch rate (same duration); predict the snapshot and the tracking bound.

    A snapshot fix uses one epoch's ranges only: its bound does not depend on the rate. A tracking
    filter (EKF-RF with the simulator's driving noise) averages over the epochs its motion model
    connects; fewer epochs per second leave it less to average, so its posterior bound rises. The
    claim is about the filter's error, which could go either way on a given set of runs: the EKF-RF's
    RMSE is higher at the lower rate (the two bounds are numbers shown beside it).

    Returns
    -------
    ExerciseCheck
        Numbers: the LS and EKF-RF bounds (cm) at both rates.
    """
    rate_hz = validate.number("rate_hz", rate_hz, minimum=0, strict_minimum=True)
    n_runs = validate.integer("n_runs", n_runs, minimum=2)
    if not rate_hz < config.rate_hz:
        raise ValueError(f"rate_hz must be below the config's {config.rate_hz:g} Hz, got {rate_hz!r}")
    methods = lambda: [CalibratedLs(), TdoaEkfEstimator("RF", grid=(1.0,))]      # noqa: E731
    fast = _summary(config, n_runs, seed, methods())
    slow = _summary(replace(config, rate_hz=rate_hz), n_runs, seed, methods())
    ls, ekf = slow.loc["LS", "bound_m"] / fast.loc["LS", "bound_m"], slow.loc["EKF-RF", "bound_m"] / fast.loc["EKF-RF", "bound_m"]
    holds = slow.loc["EKF-RF", "rmse_m"] > fast.loc["EKF-RF", "rmse_m"]
    return ExerciseCheck(f"{config.rate_hz:g} → {rate_hz:g} Hz: the EKF-RF's RMSE rises", holds,
                         {f"LS bound at {config.rate_hz:g} Hz (cm)": 100 * fast.loc["LS", "bound_m"],
                          f"LS bound at {rate_hz:g} Hz (cm)": 100 * slow.loc["LS", "bound_m"],
                          f"EKF-RF bound at {config.rate_hz:g} Hz (cm)": 100 * fast.loc["EKF-RF", "bound_m"],
                          f"EKF-RF bound at {rate_hz:g} Hz (cm)": 100 * slow.loc["EKF-RF", "bound_m"],
                          f"EKF-RF RMSE at {config.rate_hz:g} Hz (cm)": 100 * fast.loc["EKF-RF", "rmse_m"],
                          f"EKF-RF RMSE at {rate_hz:g} Hz (cm)": 100 * slow.loc["EKF-RF", "rmse_m"],
                          "LS bound ratio": ls, "EKF-RF bound ratio": ekf},
                         ("rises", "does not rise"),
                         "A snapshot fix uses one epoch's ranges, so its bound does not depend on the rate; the "
                         "tracking filter averages over the epochs its motion model connects, and fewer epochs per "
                         "second leave it less to average.")
