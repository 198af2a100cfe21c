"""Noise levels fitted from data with truth: range noise per anchor and the TDoA covariance (paper 002),
NLOS range-error percentiles per file (paper 001), the sensor-set noise model (paper 000)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..models.setnoise import SetNoiseModel
from ..types import TagRun
from .twr import MAD_TO_SIGMA


# ------------------------------------------------------- range noise per anchor, TDoA covariance (paper 002)

def range_sigma_from_truth(range_m: np.ndarray, true_range_m: np.ndarray, *, robust: bool = True) -> np.ndarray:
    """Per-anchor range-noise standard deviation from measurements with known truth.

    Parameters
    ----------
    range_m, true_range_m
        Measured and true ranges, shape ``(T, n_anchors)``, metres (NaN = missing).
    robust
        True: ``1.4826 · MAD`` of the residuals around their median (the spread,
        insensitive to NLOS outliers and to a constant bias). False: the RMS of
        the residuals (bias and outliers included: the total error a filter sees
        if nothing corrects them).

    Returns
    -------
    ndarray, shape ``(n_anchors,)``, metres
    """
    res = np.asarray(range_m, float) - np.asarray(true_range_m, float)
    if res.ndim != 2:
        raise ValueError(f"range_sigma_from_truth: need (T, n_anchors) arrays, got shape {res.shape}")
    n_ok = np.isfinite(res).sum(axis=0)
    if np.any(n_ok < 2):
        bad = np.flatnonzero(n_ok < 2).tolist()
        raise ValueError(f"range_sigma_from_truth: anchors {bad} have fewer than two residuals")
    if robust:
        med = np.nanmedian(res, axis=0)
        return MAD_TO_SIGMA * np.nanmedian(np.abs(res - med), axis=0)
    return np.sqrt(np.nanmean(res ** 2, axis=0))


def fit_range_sigma(run: TagRun, *, method: str = "tdoa", floor_m: float = 0.02) -> np.ndarray:
    """Range-noise standard deviation per anchor from a run with truth, ``(n_anchors,)``, metres.

    For the TDoA filters of notebook 03 (De Angelis, paper 002). The thesis builds its TDoA covariance from the measurement errors of its
    acquisitions; three readings of that are offered:

    ``"tdoa"`` (default)
        RMS of the range errors after removing, at every epoch, their mean over
        the anchors measured (× ``sqrt(n/(n−1))`` to undo the shrinkage for
        independent errors). A range error common to all anchors cancels in
        every TDoA, so this is the part of the error the TDoA filter sees; the
        rest (per-anchor biases, NLOS excursions) stays in.
    ``"rms"``
        RMS of the range errors themselves (common part included).
    ``"robust"``
        1.4826·MAD around the median (spread only, biases and outliers excluded).

    Values are floored at ``floor_m`` (range resolution, unmodelled effects).
    """
    err = run.ranges.range_m - run.true_range_m()
    if method == "tdoa":
        ok = np.isfinite(err)
        n = ok.sum(axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            common = np.where(n >= 2, np.nansum(np.where(ok, err, 0.0), axis=1, keepdims=True) / n, np.nan)
            shrink = np.where(n >= 2, n / np.maximum(n - 1, 1), np.nan)
        centred = (err - common) * np.sqrt(shrink)
        sig = range_sigma_from_truth(centred, np.zeros_like(centred), robust=False)
    elif method in ("rms", "robust"):
        sig = range_sigma_from_truth(run.ranges.range_m, run.true_range_m(), robust=method == "robust")
    else:
        raise ValueError(f"method must be 'tdoa', 'rms' or 'robust', got {method!r}")
    return np.maximum(sig, floor_m)


def empirical_tdoa_covariance(tdoa_m: np.ndarray, true_tdoa_m: np.ndarray, ref: int) -> np.ndarray:
    """Sample covariance of TDoA errors for a fixed reference, shape ``(n_anchors − 1, n_anchors − 1)``.

    Uses the epochs where all anchors and the reference ``ref`` were measured
    (``tdoa_m[:, ref] == 0``); rows and columns are the anchors other than
    ``ref`` in index order. Compare with :meth:`uwbwb.models.tdoa.TdoaModel.covariance`.
    """
    d = np.asarray(tdoa_m, float)
    e = d - np.asarray(true_tdoa_m, float)
    full = np.all(np.isfinite(e), axis=1) & (d[:, ref] == 0.0)
    if full.sum() < d.shape[1] + 1:
        raise ValueError(f"empirical_tdoa_covariance: only {int(full.sum())} complete epochs with reference {ref}")
    others = np.delete(np.arange(d.shape[1]), ref)
    return np.cov(e[full][:, others], rowvar=False)


# ------------------------------------------------------- NLOS range errors per file (paper 001, Hanyang)

def percentile_by_file(samples: pd.DataFrame, q: float = 5.0, min_samples: int = 20) -> pd.DataFrame:
    """Where the ``q``-th percentile of each static file's ranges lands, vs the true range.

    Parameters
    ----------
    samples
        Tidy samples with ``condition, height_m, true_range_m, range_m, file``
        (:func:`uwbwb.datasets.hanyang.load_static`).
    q
        Percentile.
    min_samples
        Files with fewer samples are left out (counted in ``attrs["n_skipped"]``):
        a 5th percentile of fewer than 20 samples is the minimum.

    Returns
    -------
    pandas.DataFrame
        One row per file: ``condition, height_m, true_range_m, n, median_err_m,
        pq_err_m`` (percentile minus true range), ``iqr_m``, ``frac_over_1m``
        (fraction of samples more than 1 m long). Possibly empty.
    """
    need = {"condition", "height_m", "true_range_m", "range_m", "file"}
    if need - set(samples.columns):
        raise ValueError(f"samples lack columns {sorted(need - set(samples.columns))}")
    err = samples["range_m"] - samples["true_range_m"]
    g = samples.assign(err=err).groupby(["file", "condition", "height_m", "true_range_m"], sort=False)["err"]
    out = pd.DataFrame({"n": g.size(), "median_err_m": g.median(), "pq_err_m": g.quantile(q / 100.0),
                        "iqr_m": g.quantile(0.75) - g.quantile(0.25),
                        "frac_over_1m": g.apply(lambda e: float(np.mean(e > 1.0)))}).reset_index()
    keep = out["n"] >= min_samples
    out = out[keep].reset_index(drop=True)
    out.attrs["n_skipped"] = int((~keep).sum())
    out.attrs["q"] = q
    return out


# ------------------------------------------------------- set-noise model (paper 000)

#: Minimum number of measurements of a set at one location for the paper's calibration to model it.
SET_MIN_COUNT = 30


def location_statistics(error_m: np.ndarray, set_id: np.ndarray, location: np.ndarray) -> pd.DataFrame:
    """Per location and set: count, mean and sample standard deviation of the fix errors.

    Parameters
    ----------
    error_m
        Fix minus true position, shape ``(N, 2)``, metres.
    set_id
        Set of each fix, shape ``(N,)``.
    location
        Calibration location label of each fix, shape ``(N,)``.

    Returns
    -------
    DataFrame
        ``location, set_id, n, mu_x_m, mu_y_m, sigma_x_m, sigma_y_m`` (σ with ``ddof=1``,
        NaN for a single measurement), sorted by location then decreasing ``n``.
    """
    error_m = np.asarray(error_m, float)
    set_id = np.asarray(set_id, np.int64)
    location = np.asarray(location)
    if error_m.ndim != 2 or error_m.shape[1] != 2 or set_id.shape != (error_m.shape[0],) \
            or location.shape != set_id.shape:
        raise ValueError(f"need error_m (N, 2), set_id (N,), location (N,); got {error_m.shape}, "
                         f"{set_id.shape}, {location.shape}")
    if not np.all(np.isfinite(error_m)):
        raise ValueError("error_m contains non-finite values")
    df = pd.DataFrame({"location": location, "set_id": set_id, "ex": error_m[:, 0], "ey": error_m[:, 1]})
    g = df.groupby(["location", "set_id"], sort=True)
    out = pd.DataFrame({"n": g.size(), "mu_x_m": g["ex"].mean(), "mu_y_m": g["ey"].mean(),
                        "sigma_x_m": g["ex"].std(ddof=1), "sigma_y_m": g["ey"].std(ddof=1)}).reset_index()
    out = out.sort_values(["location", "n", "set_id"], ascending=[True, False, True], kind="stable")
    return out.reset_index(drop=True)


def fit_set_noise(error_m: np.ndarray, set_id: np.ndarray, location: np.ndarray, *,
                  min_count: int = SET_MIN_COUNT, sigma_rule: str = "paper", min_sigma_m: float = 1e-3,
                  sensor_ids=None) -> SetNoiseModel:
    """Calibrate from fixes at known locations (paper section II-B2).

    Rules, in the paper's words and order:

    1. at each location, ``(μx, μy, σx, σy)`` of every set with at least
       ``min_count`` (30) measurements there; sets below the gate get no model
       at that location;
    2. each set's parameters are averaged across locations, weighted by the
       number of its measurements at each location;
    3. a facility-wide model — mean and standard deviation of all calibration
       errors — serves every set that has no model.

    Rule 2 applied to σ (``sigma_rule="paper"``) keeps only the spread *within*
    locations: when a set's bias changes from place to place (multipath,
    geometry), the model is overconfident away from the calibration spots.
    ``sigma_rule="pooled"`` instead uses the law of total variance over the gated
    locations, ``σ² = Σ n_l (σ_l² + (μ_l − μ)²) / Σ n_l`` — the spread of the set's
    error when the location is not known (μ is the same weighted mean).

    Parameters
    ----------
    error_m, set_id, location
        As in :func:`location_statistics` (locations: any hashable labels).
    min_count
        The per-location gate (must be ≥ 2 so that σ exists).
    min_sigma_m
        Floor on every fitted σ (quantised fixes can repeat exactly, and a zero σ
        would make eq. 9 infinite); ``meta["n_sigma_floored"]`` counts the raised values.
    sigma_rule
        ``"paper"`` (count-weighted average of σ) or ``"pooled"`` (see above).
    sensor_ids
        Sensor names for labels; defaults to ``'0'..'7'`` (or as many as the ids need).

    Returns
    -------
    SetNoiseModel
        With ``meta["per_location"]``, the table of rule 1 (all sets, gate flag included).
    """
    if sigma_rule not in ("paper", "pooled"):
        raise ValueError(f"sigma_rule must be 'paper' or 'pooled', got {sigma_rule!r}")
    if min_count < 2:
        raise ValueError(f"min_count must be >= 2 (a standard deviation needs two samples), got {min_count}")
    stats = location_statistics(error_m, set_id, location)
    stats["gated_in"] = stats["n"] >= min_count
    kept = stats[stats["gated_in"]]
    w = kept["n"].to_numpy(float)
    grp = kept.groupby("set_id", sort=True)
    cols = ["mu_x_m", "mu_y_m", "sigma_x_m", "sigma_y_m"]
    weighted = kept[cols].mul(w, axis=0).groupby(kept["set_id"], sort=True).sum()
    n_set = grp["n"].sum()
    avg = weighted.div(n_set.astype(float), axis=0)
    err = np.asarray(error_m, float)
    if err.shape[0] < 2:
        raise ValueError("the facility-wide model needs at least two calibration measurements")
    if sensor_ids is None:
        top = int(np.max(np.asarray(set_id, np.int64))).bit_length()
        sensor_ids = tuple(str(i) for i in range(max(8, top)))
    sigma = avg[["sigma_x_m", "sigma_y_m"]].to_numpy(float)
    if sigma_rule == "pooled":
        mean_of_set = avg.loc[kept["set_id"], ["mu_x_m", "mu_y_m"]].to_numpy()
        spread = kept[["sigma_x_m", "sigma_y_m"]].to_numpy() ** 2 \
            + (kept[["mu_x_m", "mu_y_m"]].to_numpy() - mean_of_set) ** 2
        var = pd.DataFrame(spread * w[:, None]).groupby(kept["set_id"].to_numpy(), sort=True).sum()
        sigma = np.sqrt(var.to_numpy() / n_set.to_numpy(float)[:, None])
    default_sigma = err.std(axis=0, ddof=1)
    n_floored = int(np.sum(sigma < min_sigma_m) + np.sum(default_sigma < min_sigma_m))
    return SetNoiseModel(set_id=avg.index.to_numpy(np.int64),
                         mu_m=avg[["mu_x_m", "mu_y_m"]].to_numpy(float),
                         sigma_m=np.maximum(sigma, min_sigma_m),
                         n=n_set.to_numpy(np.int64),
                         default_mu_m=err.mean(axis=0), default_sigma_m=np.maximum(default_sigma, min_sigma_m),
                         default_n=err.shape[0], sensor_ids=sensor_ids,
                         meta={"per_location": stats, "min_count": min_count, "sigma_rule": sigma_rule,
                               "min_sigma_m": min_sigma_m, "n_sigma_floored": n_floored})


def fit_set_noise_from_fixes(logs, *, min_count: int = SET_MIN_COUNT, sigma_rule: str = "paper") -> SetNoiseModel:
    """:func:`fit_set_noise` on calibration logs, one :class:`~uwbwb.types.SetFixLog` (with truth) per location.

    The logs' names label the locations, so they must be distinct.
    """
    logs = list(logs)
    if not logs:
        raise ValueError("no calibration logs")
    names = [log.name for log in logs]
    if len(set(names)) != len(names):
        raise ValueError(f"calibration logs need distinct names (they label the locations), got {names}")
    ids = logs[0].sensor_ids
    if any(log.sensor_ids != ids for log in logs):
        raise ValueError("calibration logs use different sensors")
    return fit_set_noise(np.concatenate([log.error_m for log in logs]), np.concatenate([log.set_id for log in logs]),
                         np.repeat(np.array(names, dtype=object), [len(log) for log in logs]),
                         min_count=min_count, sigma_rule=sigma_rule, sensor_ids=ids)
