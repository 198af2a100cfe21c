"""Notebook 02's comparison with the paper, decided by intervals on the run's own errors.

Every verdict comes from an interval and :func:`uwbwb.metrics.interval_side`: a difference of two estimators'
median errors on the epochs (or stops) both covered gets the block-bootstrap interval of
:func:`uwbwb.metrics.block_bootstrap_difference` (:func:`paired`); the paper's "90 % of all distance errors under
4 m" gets the interval over independent simulated experiments of :func:`uwbwb.metrics.seeds_interval`. With too
few blocks (or one experiment, as in FAST) a row has no interval and says "no interval", never a verdict.
:func:`verdict_table` lays the claims out as rows (:data:`COLUMNS`: claim, paper and its kind, ours with its 95 %
interval and count, its kind, the simulator assumption a synthetic number rests on, rule, verdict); a ranking's
``ours`` is its ranks, and a row per pair of the ranking follows it. :func:`wins_table` says which estimator leads
where, by the same rule.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ... import metrics
from ...sim.tours import TourConfig
from .scoring import ESTIMATORS, LABELS, PAPER_RANKING, POINT

__all__ = ["COLUMNS", "Ranking", "assumption", "noise", "paired", "ranking", "rankings", "verdict_table", "wins_table"]

#: The columns of :func:`verdict_table`.
COLUMNS = ["claim", "paper", "paper kind", "ours", "95 % low", "95 % high", "n", "ours kind", "assumption", "rule",
           "verdict"]


def _sides(below: str, above: str) -> dict:
    """Verdicts of a difference ``a − b`` from the side of its interval (:func:`uwbwb.metrics.interval_side`)."""
    return {"below": below, "above": above, "contains": "not significant", "none": "no interval"}


_NLS = _sides("NLS better", "NLS worse")
#: Verdicts of "90 % of all distance errors under 4 m" from the side of its interval against 4 m.
_UNDER = {"below": "agrees", "above": "differs", "contains": "not resolved", "none": "no interval"}
#: Rule text of the paired rows.
_PAIRED_RULE = "95 % block-bootstrap interval of the median difference vs 0"
_RANK_RULE = ("each step of the paper's order: 95 % block-bootstrap interval of the median difference below 0 (all: "
              "as in the paper; one above 0: differs); rank: 1 + the number ranked above, a heuristic ranked above "
              "another only where every pair's interval resolves it (otherwise they share a rank)")
_SEEDS_RULE = ("95 % Student-t interval, over the simulated experiments (independent draws), of their 90th "
               "percentile vs 4 m")


def paired(table: pd.DataFrame, a: str, b: str, series: list[str], *, at: str = "t_s", by: str = "heuristic",
           column: str = "err_m", blocks: str = "acf", rng: np.random.Generator) -> dict:
    """``median(a) − median(b)`` of two rows of ``table`` (named in column ``by``) over the ``(series, at)`` keys both
    have a finite ``column`` for, with its block-bootstrap interval (one series per value of ``series``, ordered by
    ``at``; ``blocks`` as in :func:`uwbwb.metrics.block_bootstrap_difference`) and its side of 0
    (:func:`uwbwb.metrics.interval_side`)."""
    wide = table.pivot_table(index=[*series, at], columns=by, values=column).reindex(columns=[a, b]).dropna()
    groups = [g for _, g in wide.sort_index().groupby(level=list(range(len(series))), sort=True)]
    d = metrics.block_bootstrap_difference([g[a].to_numpy() for g in groups], [g[b].to_numpy() for g in groups],
                                           rng=rng, statistic="median", blocks=blocks)
    return {**d, "a": a, "b": b, "side": metrics.interval_side(d["lo_m"], d["hi_m"])}


def _decide(steps: list[dict], holds: str, fails: str) -> str:
    """The verdict of the paired differences ``steps`` (each ``a < b`` claimed): every interval below 0, ``holds``;
    one above 0, ``fails``; no interval at all, "no interval"; else not resolved."""
    sides = [s["side"] for s in steps]
    if sides and all(x == "below" for x in sides):
        return holds
    if "above" in sides:
        return fails
    return "no interval" if all(x == "none" for x in sides) else "not resolved"


@dataclass(frozen=True)
class Ranking:
    """The paper's three heuristics ranked by median stop error, each order decided by an interval (:func:`ranking`).

    Attributes
    ----------
    pairs
        :func:`paired` of every pair of them: first the steps of the paper's order (residual pruning − robust mean,
        robust mean − 5th percentile), then the rest.
    rank
        Per heuristic (lowest median first): its rank by :func:`uwbwb.metrics.tied_ranks` from the pairs the
        intervals resolve (no interval at all: all 1).
    """

    pairs: tuple
    rank: pd.Series

    def hidden(self) -> list[tuple[str, str]]:
        """``(better, worse)`` of every pair an interval resolves that the ranks tie: an order that is not transitive
        (a ≈ b, a ≈ c, yet b better than c) and that tied groups cannot show."""
        return [(d["a"], d["b"]) if d["side"] == "below" else (d["b"], d["a"]) for d in self.pairs
                if d["side"] in ("below", "above") and self.rank[d["a"]] == self.rank[d["b"]]]

    def note(self) -> str:
        """What the ties hide (:meth:`hidden`), e.g. "; inside the tie, robust mean resolved better than residual
        pruning"; empty when nothing is hidden."""
        return "".join(f"; inside the tie, {LABELS[a]} resolved better than {LABELS[b]}" for a, b in self.hidden())

    def text(self) -> str:
        """The ranks in words, e.g. "robust mean 1, 5th percentile 1, residual pruning 3", and :meth:`note`."""
        return ", ".join(f"{LABELS[h]} {r}" for h, r in self.rank.items()) + self.note()


def ranking(stops: pd.DataFrame, series: list[str], *, at: str = "segment", rng: np.random.Generator) -> Ranking:
    """Rank the paper's three heuristics present in ``stops`` (one error ``err_m`` per stop, ``heuristic``) by every
    pair's median difference on the stops both fitted, with its block-bootstrap interval (:func:`paired`, each
    series of ``series`` one block, ordered by ``at``), walking up the medians by :func:`uwbwb.metrics.tied_ranks`;
    see :class:`Ranking`."""
    order = [h for h in PAPER_RANKING if h in set(stops["heuristic"])]
    steps = list(zip(order[:-1], order[1:]))
    pairs = tuple(paired(stops, a, b, series, at=at, blocks="segment", rng=rng)
                  for a, b in steps + [p for p in itertools.combinations(order, 2) if p not in steps])
    better = {(d["a"], d["b"]) if d["side"] == "below" else (d["b"], d["a"]) for d in pairs
              if d["side"] in ("below", "above")}
    medians = stops[stops["heuristic"].isin(order)].groupby("heuristic")["err_m"].median().sort_values()
    return Ranking(pairs, pd.Series(metrics.tied_ranks(medians.index, better), name="rank", dtype=int))


def _same_order(a: Ranking, b: Ranking) -> str:
    """Whether two rankings of the same heuristics (:func:`ranking`: ties where an interval does not resolve the
    order) give the same order of the heuristics both hold: "same" (every pair resolved in both, the same way),
    "changes" (a pair resolved in both, the other way), "no interval" (no interval in ``b``) or "not resolved"."""
    both = [h for h in b.rank.index if h in a.rank.index]
    pairs = [(a.rank[h] - a.rank[g], b.rank[h] - b.rank[g]) for h, g in itertools.combinations(both, 2)]
    if any(x * y < 0 for x, y in pairs):
        return "changes"
    if pairs and all(x * y > 0 for x, y in pairs):
        return "same"
    return "no interval" if all(d["side"] == "none" for d in b.pairs) else "not resolved"


def rankings(syn, lias=None, *, seed: int = 0) -> dict[str, Ranking]:
    """The :class:`Ranking` of every stop table the notebook ranks: ``"synthetic"`` (``syn.stops``, each experiment
    and node one block) and each LIAS static run by its name (its poses, each pose one block). The verdict table's
    ranking rows and the summary's rank rows both read these."""
    rng = np.random.default_rng(seed)
    out = {"synthetic": ranking(syn.stops, ["experiment", "tag"], rng=rng)}
    for k, run in (lias.runs.items() if lias is not None else ()):
        out[k] = ranking(run.poses, ["recording"], at="tag", rng=rng)
    return out


def _p90(track: pd.DataFrame) -> dict:
    """The mean of the experiments' own 90th percentiles of the covered packets, its interval and its side of 4 m,
    under the keys of :func:`paired` that a verdict row reads (``diff_m`` holds the mean, not a difference)."""
    e = track.dropna(subset=["err_m"])
    s = metrics.seeds_interval(e.groupby("experiment")["err_m"].quantile(0.9))
    return {"diff_m": s["mean"], "lo_m": s["lo"], "hi_m": s["hi"], "n": s["n"],
            "side": metrics.interval_side(s["lo"], s["hi"], 4.0)}


#: Whose range errors a synthetic row rests on.
_OURS = "our simulator (uw.sim.tours.TourConfig), not the paper's"


def assumption(tour: TourConfig | None) -> str:
    """The simulator assumption a synthetic row rests on, with its values when the configuration was given."""
    if tour is None:
        return f"simulated range errors: {_OURS}"
    return (f"{noise(tour)} ({100 * tour.p_nlos_in:.0f} % inside), per-pair bias "
            f"{tour.bias_range_m[0]:g}–{tour.bias_range_m[1]:g} m: {_OURS}")


def noise(tour: TourConfig) -> str:
    """The simulated range noise in a phrase: NLOS excess, its share of links outside coverage, episodes, LOS σ."""
    return (f"NLOS excess N({tour.nlos_mean_m:g} m, {tour.nlos_sigma_m:g} m) clipped at 0 on "
            f"{100 * tour.p_nlos_out:.0f} % of links outside coverage, {tour.nlos_dwell_s:g} s episodes, "
            f"LOS σ {tour.sigma_m:g} m")


def verdict_table(syn, *, dim: int = 2, other=None, tour: TourConfig | None = None,
                  persistence: pd.DataFrame | None = None, excess: pd.DataFrame | None = None, lias=None,
                  lias_dyn=None, hanyang: pd.DataFrame | None = None, ranks: dict | None = None,
                  seed: int = 0) -> pd.DataFrame:
    """The claims of notebook 02, one row each (:data:`COLUMNS`), each decided by an interval; each ranking row
    (ours: its ranks) is followed by a row per pair of the ranking.

    Parameters
    ----------
    syn
        The ranked synthetic comparison (:class:`~.study.SyntheticResult`: ``stops``, ``track``).
    dim
        Its geometry (2: known mount height, 3: no height).
    other
        The same packets in the other geometry (:class:`~.study.SyntheticResult`; None: no 3-D rows).
    tour
        The simulator configuration (named in the ``assumption`` column; None: named without its values).
    persistence
        Stops (:attr:`~.study.SyntheticResult.stops`) of runs that differ in ``TourConfig.nlos_dwell_s``, which
        column ``nlos_dwell_s`` holds.
    excess
        Residual pruning's packets (:attr:`~.study.SyntheticResult.track`) of runs that differ in
        ``TourConfig.nlos_mean_m``, which column ``nlos_mean_m`` holds.
    lias, lias_dyn
        :func:`~.sections.lias_static` and :func:`~.sections.lias_dynamic` (None: no LIAS rows).
    hanyang
        :func:`uwbwb.calibration.percentile_by_file` of the Hanyang static files (LOS and NLOS paired by height and
        true range).
    ranks
        :func:`rankings` of ``syn`` and ``lias`` (None: computed here with ``seed``), which the ranking rows read.
    seed
        Seeds the bootstrap of every row.

    ``paper kind`` is *input* where the paper states the claim, ``ours kind`` *reproduced*. Where a contender is
    needed it is fixed before looking (residual pruning, the paper's best heuristic; plain NLS, the trajectory fit
    itself), not picked as the lowest median of the same data.
    """
    rng = np.random.default_rng(seed)
    rows = []

    def add(claim, paper, ours, rule, verdict, assumption="—", d=None):
        """One row; ``d`` (:func:`paired`, or :func:`_p90`) gives ``ours``, its interval, count and verdict."""
        if d is not None:
            ours, verdict = d["diff_m"], verdict[d["side"]]
        rows.append({"claim": claim, "paper": paper, "paper kind": "—" if paper == "—" else "input", "ours": ours,
                     "95 % low": np.nan if d is None else d["lo_m"], "95 % high": np.nan if d is None else d["hi_m"],
                     "n": np.nan if d is None else d["n"], "ours kind": "reproduced", "assumption": assumption,
                     "rule": rule, "verdict": verdict})

    def each_pair(pairs, what: str, blocks: str, assumption="—", where="row above"):
        """A row per paired difference behind the row above (what it differences, and in which blocks)."""
        for d in pairs:
            a, b = LABELS[d["a"]], LABELS[d["b"]]
            add(f"pair of the {where}: {a} − {b}, median {what} (m)", "—", None, _PAIRED_RULE + blocks,
                _sides(f"{a} lower", f"{b} lower"), assumption, d)

    syn_a = assumption(tour)
    geo = "known mount height" if dim == 2 else "3-D, no height"
    ranks = rankings(syn, lias, seed=seed) if ranks is None else ranks
    paper_order = " < ".join(LABELS[h] for h in PAPER_RANKING)

    def ranked(claim: str, r: Ranking, rule: str, what: str, blocks: str, assumption="—"):
        """A ranking row (ours: the ranks, tied where not resolved; the paper's steps decide) and its pairs."""
        add(claim, paper_order, r.text(), rule + _RANK_RULE, _decide(list(r.pairs[:max(len(r.rank) - 1, 0)]),
                                                                     "as in the paper", "differs"), assumption)
        each_pair(r.pairs, what, blocks, assumption, "ranking above")

    ranked(f"ranking of the heuristics by median stop error, synthetic ({geo})", ranks["synthetic"],
           "each experiment's series of stops one block; ", "stop error", " (each experiment's stops one block)", syn_a)
    track = syn.track
    if {"residual", POINT} <= set(track["heuristic"]):
        add("residual pruning (fixed in advance) vs the point-based fixes, median of all distance errors on the "
            "packets both covered (m)", "a slight improvement", None, _PAIRED_RULE + " (each experiment and node one "
            "block)", _NLS, syn_a, paired(track, "residual", POINT, ["experiment", "tag"], blocks="segment", rng=rng))
    if "residual" in set(track["heuristic"]):
        add("residual pruning: 90 % of all distance errors under 4 m (mean of the experiments' 90th percentiles, m)",
            "yes (the paper's cafeteria)", None, _SEEDS_RULE, _UNDER, syn_a,
            _p90(track[track["heuristic"] == "residual"]))
    for m, t in (excess.groupby("nlos_mean_m") if excess is not None and len(excess) else ()):
        add(f"residual pruning: 90 % of all distance errors under 4 m, as the simulated NLOS excess is scaled: "
            f"{m:g} m (mean of the experiments' 90th percentiles, m)", "yes (the paper's cafeteria)", None,
            _SEEDS_RULE, _UNDER, f"nlos_mean_m scaled, the rest as above: {_OURS}", _p90(t))
    if other is not None:
        three_d, known = (other, syn) if dim == 2 else (syn, other)
        present = set(three_d.stops["heuristic"])
        flat = ranks["synthetic"] if dim == 2 else ranking(known.stops, ["experiment", "tag"], rng=rng)
        up = ranking(three_d.stops.assign(err_m=three_d.stops["err_3d_m"]), ["experiment", "tag"], rng=rng)
        add("the known-height ranking in 3-D without a height, by 3-D median error (the robust mean has no 3-D "
            "version)", "—", f"known height: {flat.text()}; 3-D: {up.text()}", "each order by the ranking rule "
            "(each experiment's stops one block; 3-D: the 3-D error): every pair of the heuristics in both resolved "
            "in both and the same, same; one resolved the other way, changes; else not resolved",
            _same_order(flat, up), syn_a)
        each_pair(up.pairs, "3-D stop error", " (each experiment's stops one block)", syn_a)
        if "percentile" in present:
            dz = three_d.stops[three_d.stops["heuristic"] == "percentile"]
            add("5th percentile in 3-D: median height error (m; > 0: the node sits too high)", "—", None,
                _PAIRED_RULE + " (each experiment's stops one block)", _sides("too low", "too high"), syn_a,
                paired(pd.concat([dz, dz.assign(heuristic="0", err_z_m=0.0)]), "percentile", "0",
                       ["experiment", "tag"], at="segment", column="err_z_m", blocks="segment", rng=rng))
    if persistence is not None and persistence["nlos_dwell_s"].nunique() >= 2:
        dwell = sorted(persistence["nlos_dwell_s"].unique())
        base, long = (3.0 if 3.0 in dwell else dwell[0]), dwell[-1]
        at = {w: persistence[persistence["nlos_dwell_s"] == w] for w in (base, long)}
        three = [h for h in PAPER_RANKING if h in set(persistence["heuristic"])]
        first = ranking(at[base], ["experiment", "tag"], rng=rng)       # best at the base: ranked alone first
        top = list(first.rank.index[first.rank == 1])
        steps = [paired(at[long], top[0], h, ["experiment", "tag"], at="segment", blocks="segment", rng=rng)
                 for h in three if h != top[0]]
        verdict = _decide(steps, "same", "changes")
        if len(top) > 1:
            verdict = "no interval" if all(d["side"] == "none" for d in first.pairs) else "not resolved"
        add(f"the best heuristic at {base:g} s NLOS episodes ({', '.join(LABELS[h] for h in top)}"
            f"{'' if len(top) == 1 else ': tied'}) still best at {long:g} s", "—", f"{base:g} s: {first.text()}",
            f"best at {base:g} s: ranked alone first there (the ranking row's rank rule); then the 95 % bootstrap "
            f"interval of its median difference to each other heuristic at {long:g} s (each experiment's stops one "
            "block): all below 0 same, one above 0 changes", verdict, f"nlos_dwell_s varied, the rest as above: {_OURS}")
        each_pair(steps, f"stop error at {long:g} s", " (each experiment's stops one block)",
                  f"nlos_dwell_s varied, the rest as above: {_OURS}")
    for k in (lias.runs if lias is not None else ()):
        if len(ranks[k].rank) >= 2:
            ranked(f"LIAS static, {k} ranges: the heuristics ranked by median pose error", ranks[k],
                   "each pose one block; ", "pose error", " (each pose one block)")
    for k, run in (lias.runs.items() if lias is not None else ()):
        add(f"LIAS static, {k} ranges: plain NLS (fixed in advance) vs point fixes, median error on common epochs (m)",
            "—", None, _PAIRED_RULE + " (each pose one block)", _NLS, d=paired(
                run.epochs, "none", POINT, ["recording", "tag"], blocks="segment", rng=rng))
    if lias is not None and "calibrated (LOSO)" in lias.runs:
        poses = pd.concat([lias.runs["calibrated (LOSO)"].poses.query("heuristic == 'none'").assign(heuristic="calibrated"),
                           lias.runs["raw"].poses.query("heuristic == 'residual'")])
        add("LIAS static: range calibration (plain NLS) vs residual pruning (raw ranges, fixed in advance), median "
            "error on the same poses (m)", "—", None, _PAIRED_RULE + " (each pose one block)",
            _sides("calibration better", "pruning better"),
            d=paired(poses, "calibrated", "residual", ["recording"], at="tag", blocks="segment", rng=rng))
    for k, run in (lias_dyn.runs.items() if lias_dyn is not None else ()):
        add(f"LIAS dynamic, {k} ranges: residual pruning (fixed in advance) vs plain NLS, median error on common "
            "epochs (m)", "—", None, _PAIRED_RULE, _sides("residual pruning better", "plain NLS better"),
            d=paired(run.epochs, "residual", "none", ["segment", "tag"], rng=rng))
        add(f"LIAS dynamic, {k} ranges: plain NLS (fixed in advance) vs point fixes, median error on common epochs "
            "(m)", "—", None, _PAIRED_RULE, _NLS, d=paired(run.epochs, "none", POINT, ["segment", "tag"], rng=rng))
    if hanyang is not None and {"LOS", "NLOS"} <= set(hanyang["condition"]):
        add("Hanyang static: NLOS − LOS median range error, files paired by height and range (m)", "—", None,
            _PAIRED_RULE + " (each height one block)", _sides("NLOS smaller", "NLOS larger"),
            d=paired(hanyang, "NLOS", "LOS", ["height_m"], at="true_range_m", by="condition", column="median_err_m",
                     blocks="segment", rng=rng))
    return pd.DataFrame(rows, columns=COLUMNS).astype({"n": "Int64"})


#: The wins table's lead from the side of the interval of ``leader − runner-up``.
_LEAD = {"below": "{a}", "above": "{b} (on the epochs both covered)", "contains": "not resolved: {a} vs {b}",
         "none": "no interval: {a} vs {b}"}


def wins_table(entries: dict, *, seed: int = 0) -> pd.DataFrame:
    """Which estimator leads where: ``entries`` maps a row name to ``(epochs, series, blocks)`` (an epoch table,
    its series columns and :func:`paired`'s block rule).

    Columns: the median error per estimator (:data:`ESTIMATORS` order), then ``best of all`` and ``best heuristic``
    (among the paper's three): the lowest median, if the interval of its median difference to the second lowest on
    the epochs both covered lies below 0; otherwise "not resolved" (or "no interval") with both named.
    """
    rng = np.random.default_rng(seed)
    out = {}
    for row, (epochs, series, blocks) in entries.items():
        med = epochs.groupby("heuristic")["err_m"].median()
        r = {h: med[h] for h in ESTIMATORS if h in med.index}
        for col, pool in (("best of all", list(r)), ("best heuristic", [h for h in PAPER_RANKING if h in r])):
            m = med[pool].dropna().sort_values()
            if len(m) < 2:
                r[col] = LABELS[m.index[0]] if len(m) else "—"
                continue
            d = paired(epochs, m.index[0], m.index[1], series, blocks=blocks, rng=rng)
            r[col] = _LEAD[d["side"]].format(a=LABELS[m.index[0]], b=LABELS[m.index[1]])
        out[row] = r
    return pd.DataFrame.from_dict(out, orient="index")
