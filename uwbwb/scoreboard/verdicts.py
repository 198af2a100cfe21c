"""Verdicts of a board, computed from facts with intervals (notebook 06's "what the boards say").

Two kinds of statement, each a ``facts`` function returning the numbers and the rule, and a
``sentence`` template over them (tests feed values on both sides of each threshold):

* :func:`difference_facts` / :func:`difference_sentence` — method A against method B: the
  difference of their RMSEs on the epochs *both* covered, with a 95 % moving-block bootstrap
  interval (blocks of ``ceil(sqrt(n))`` consecutive epochs per tag, so that the correlation of a
  tracking filter's errors is kept). The verdict is "A more accurate" / "B more accurate" when the
  interval excludes 0, else "no significant difference".
* :func:`placement_facts` / :func:`placement_sentence` — a method against the recording's common
  bound (:mod:`.reference`): RMSE / common bound with its block standard error; "above the
  bound" when ``ratio − 2 se > 1``, "below the bound" when ``ratio + 2 se < 1`` (with what that
  means), else "on the bound".
"""

from __future__ import annotations

import numpy as np

__all__ = ["N_BOOT", "difference_facts", "difference_sentence", "placement_facts", "placement_sentence"]

#: Bootstrap resamples of a difference.
N_BOOT = 2000


def _block_resample(n: int, rng: np.random.Generator, n_boot: int) -> np.ndarray:
    """Indices ``(n_boot, n)`` of moving-block resamples of ``n`` consecutive epochs."""
    L = max(1, int(np.ceil(np.sqrt(n))))
    k = int(np.ceil(n / L))
    starts = rng.integers(0, n - L + 1, size=(n_boot, k))
    return (starts[:, :, None] + np.arange(L)).reshape(n_boot, -1)[:, :n]


def difference_facts(board, a: str, b: str, *, n_boot: int = N_BOOT, rng: np.random.Generator) -> dict:
    """RMSE of ``a`` minus RMSE of ``b`` on the epochs both covered, with its 95 % block-bootstrap interval.

    Returns
    -------
    dict
        ``a, b, n_epochs, rmse_a_m, rmse_b_m, diff_m, lo_m, hi_m, verdict`` (``"a"``, ``"b"`` or
        ``"none"``: which is more accurate, by the rule that the interval excludes 0), ``mode``.
    """
    sa, sb, boot_a, boot_b = [], [], [], []
    for tag in board.tags:
        ea, eb = board.entry(a, tag), board.entry(b, tag)
        if ea.skipped or eb.skipped:
            continue
        both = ea.scored & eb.scored
        if both.sum() < 2:
            continue
        sa.append(ea.error_m[both] ** 2)
        sb.append(eb.error_m[both] ** 2)
    out = {"a": a, "b": b, "mode": board.mode, "n_epochs": int(sum(x.size for x in sa))}
    if out["n_epochs"] < 2:
        return {**out, "rmse_a_m": np.nan, "rmse_b_m": np.nan, "diff_m": np.nan, "lo_m": np.nan, "hi_m": np.nan,
                "verdict": "none"}
    # resample each tag's epochs by blocks, pool the tags
    tot_a = np.zeros(n_boot)
    tot_b = np.zeros(n_boot)
    for xa, xb in zip(sa, sb):
        idx = _block_resample(xa.size, rng, n_boot)
        tot_a += xa[idx].sum(axis=1)
        tot_b += xb[idx].sum(axis=1)
    n = out["n_epochs"]
    d = np.sqrt(tot_a / n) - np.sqrt(tot_b / n)
    rmse_a, rmse_b = float(np.sqrt(np.concatenate(sa).mean())), float(np.sqrt(np.concatenate(sb).mean()))
    lo, hi = (float(v) for v in np.percentile(d, [2.5, 97.5]))
    return {**out, "rmse_a_m": rmse_a, "rmse_b_m": rmse_b, "diff_m": rmse_a - rmse_b, "lo_m": lo, "hi_m": hi,
            "verdict": "a" if hi < 0 else ("b" if lo > 0 else "none")}


def difference_sentence(f: dict) -> str:
    """One sentence from :func:`difference_facts`."""
    if f["n_epochs"] < 2:
        return f"{f['a']} vs {f['b']}: no epochs that both covered ({f['mode']})."
    head = (f"{f['a']} − {f['b']}: RMSE {f['rmse_a_m']:.3f} vs {f['rmse_b_m']:.3f} m on the {f['n_epochs']} epochs "
            f"both covered, difference {1000 * f['diff_m']:+.1f} mm, 95 % block-bootstrap interval "
            f"[{1000 * f['lo_m']:+.1f}, {1000 * f['hi_m']:+.1f}] mm ({f['mode']})")
    if f["verdict"] == "a":
        return head + f": {f['a']} is more accurate."
    if f["verdict"] == "b":
        return head + f": {f['b']} is more accurate."
    return head + ": the interval includes 0 — no significant difference."


def placement_facts(row) -> dict:
    """Where one board row (:meth:`Board.table`) sits against the common bound: ``above``, ``on``, ``below`` or ``none``."""
    r, se = float(row.rmse_over_common), float(row.rmse_over_common_se)
    if not np.isfinite(r):
        where = "none"
    else:
        s = se if np.isfinite(se) else 0.0
        where = "above" if r - 2 * s > 1 else ("below" if r + 2 * s < 1 else "on")
    return {"method": row.method, "ratio": r, "se": se, "where": where}


def placement_sentence(f: dict) -> str:
    """One sentence from :func:`placement_facts`."""
    if f["where"] == "none":
        return f"{f['method']}: no common bound on its epochs."
    se = f" ± {f['se']:.2f}" if np.isfinite(f["se"]) else ""
    head = f"{f['method']}: RMSE / common bound {f['ratio']:.2f}{se}"
    if f["where"] == "above":
        return head + (" — above the common bound by more than 2 standard errors: room to improve under the bound's "
                       "model, or errors that its unbiased Gaussian range noise leaves out (biases, multipath).")
    if f["where"] == "below":
        return head + (" — below the common bound by more than 2 standard errors: it uses information the bound "
                       "does not (an IMU, or later ranges: a smoother), or the track is smoother than the fitted "
                       "motion model.")
    return head + " — on the common bound within 2 standard errors."
