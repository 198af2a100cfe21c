"""Notebook 02's comparison with the paper, decided by intervals on the run's own errors.

Every verdict comes from an interval and :func:`uwbwb.metrics.interval_side`: a difference of two estimators'
median errors on the epochs (or stops) both covered gets the block-bootstrap interval of
:func:`uwbwb.metrics.block_bootstrap_difference` (:func:`paired`); the paper's "90 % of all distance errors under
4 m" gets the interval over independent simulated experiments of :func:`uwbwb.metrics.seeds_interval`. With too
few blocks (or one experiment, as in FAST) a row says "no interval", never a verdict. :func:`verdict_table` lays the
claims out as rows (claim, paper and its kind, ours and its kind, the simulator assumption a synthetic number rests
on, rule, verdict); :func:`wins_table` says which estimator leads where, by the same rule.
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
COLUMNS = ["claim", "paper", "paper kind", "ours", "ours kind", "assumption", "rule", "verdict"]


def _sides(below: str, above: str) -> dict:
    """Verdicts of a difference ``a − b`` from the side of its interval (:func:`uwbwb.metrics.interval_side`)."""
    return {"below": below, "above": above, "contains": "not significant", "none": "no interval"}


_NLS = _sides("NLS better", "NLS worse")
#: Verdicts of "90 % of all distance errors under 4 m" from the side of its interval against 4 m.
_UNDER = {"below": "agrees", "above": "differs", "contains": "not resolved", "none": "no interval"}
#: The scaled-excess row's verdict from the sides of its intervals (any other mix: not resolved).
_EXCESS = {frozenset({"below"}): "agrees at each", frozenset({"above"}): "differs at each",
           frozenset({"below", "above"}): "depends on the assumed excess", frozenset({"none"}): "no interval"}
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


def _iv(d: dict, digits: int = 2) -> str:
    return f"[{d['lo_m']:+.{digits}f}, {d['hi_m']:+.{digits}f}]" if d["side"] != "none" else "(no interval)"


def _pair_text(d: dict, what: str, digits: int = 3) -> str:
    a, b = (LABELS.get(d[k], d[k]) for k in ("a", "b"))
    return (f"{a} {d['median_a_m']:.{digits}f}, {b} {d['median_b_m']:.{digits}f}: {d['diff_m']:+.{digits}f} "
            f"{_iv(d, digits)} ({d['n']} {what})")


def _decide(steps: list[dict], holds: str, fails: str, what: str = "stops") -> tuple[str, str]:
    """The text of the paired differences ``steps`` (each ``a < b`` claimed; ``what`` they count) and their verdict:
    every interval below 0, ``holds``; one above 0, ``fails``; no interval at all, "no interval"; else not
    resolved."""
    sides = [s["side"] for s in steps]
    text = "; ".join(f"{LABELS[s['a']]} − {LABELS[s['b']]} {s['diff_m']:+.2f} m {_iv(s)}" for s in steps) + (
        f" ({steps[0]['n']} {what})" if steps else "")
    if sides and all(x == "below" for x in sides):
        return text, holds
    if "above" in sides:
        return text, fails
    return text, ("no interval" if all(x == "none" for x in sides) else "not resolved")


@dataclass(frozen=True)
class Ranking:
    """The paper's three heuristics ranked by median stop error, each order decided by an interval (:func:`ranking`).

    Attributes
    ----------
    pairs
        :func:`paired` of every pair of them: first the steps of the paper's order (residual pruning − robust mean,
        robust mean − 5th percentile), then the rest.
    rank
        Per heuristic (lowest median first): 1 + the number ranked above it, where a heuristic is ranked above
        another only when every interval resolves it (tied groups: each heuristic ranked above a group is resolved
        better than every one in it; no interval at all: all 1).
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
    series of ``series`` one block, ordered by ``at``); see :class:`Ranking`. Walking up the medians, a heuristic
    opens a group only when every one before it is resolved better; otherwise it joins, with every group after the
    first one holding a heuristic not resolved better than it."""
    order = [h for h in PAPER_RANKING if h in set(stops["heuristic"])]
    steps = list(zip(order[:-1], order[1:]))
    pairs = tuple(paired(stops, a, b, series, at=at, blocks="segment", rng=rng)
                  for a, b in steps + [p for p in itertools.combinations(order, 2) if p not in steps])
    better = {(d["a"], d["b"]) if d["side"] == "below" else (d["b"], d["a"]) for d in pairs
              if d["side"] in ("below", "above")}
    groups = []
    for h in stops[stops["heuristic"].isin(order)].groupby("heuristic")["err_m"].median().sort_values().index:
        i = next((j for j, g in enumerate(groups) if any((m, h) not in better for m in g)), len(groups))
        groups = groups[:i] + [[m for g in groups[i:] for m in g] + [h]]
    rank = {h: 1 + sum(map(len, groups[:j])) for j, g in enumerate(groups) for h in g}
    return Ranking(pairs, pd.Series(rank, name="rank", dtype=int))


def _same_order(a: Ranking, b: Ranking) -> tuple[str, str]:
    """Whether two rankings of the same heuristics (:func:`ranking`: ties where an interval does not resolve the
    order) give the same order of the heuristics both hold: ``b``'s differences and ranks in words, and "same"
    (every pair resolved in both, the same way), "changes" (a pair resolved in both, the other way), "no interval"
    (no interval in ``b``) or "not resolved"."""
    both = [h for h in b.rank.index if h in a.rank.index]
    pairs = [(a.rank[h] - a.rank[g], b.rank[h] - b.rank[g]) for h, g in itertools.combinations(both, 2)]
    text = _decide(list(b.pairs), "", "")[0] + (f"; rank (tied where not resolved): {b.text()}" if len(b.rank) else "")
    if any(x * y < 0 for x, y in pairs):
        return text, "changes"
    if pairs and all(x * y > 0 for x, y in pairs):
        return text, "same"
    return text, ("no interval" if all(d["side"] == "none" for d in b.pairs) else "not resolved")


def rankings(syn, lias=None, *, seed: int = 0) -> dict[str, Ranking]:
    """The :class:`Ranking` of every stop table the notebook ranks: ``"synthetic"`` (``syn.stops``, each experiment
    and node one block) and each LIAS static run by its name (its poses, each pose one block). The verdict table's
    ranking rows and the summary's rank rows both read these."""
    rng = np.random.default_rng(seed)
    out = {"synthetic": ranking(syn.stops, ["experiment", "tag"], rng=rng)}
    for k, run in (lias.runs.items() if lias is not None else ()):
        out[k] = ranking(run.poses, ["recording"], at="tag", rng=rng)
    return out


def _p90(track: pd.DataFrame) -> tuple[float, dict]:
    """Pooled 90th percentile of the covered packets, and the interval of the experiments' own 90th percentiles."""
    e = track.dropna(subset=["err_m"])
    s = metrics.seeds_interval(e.groupby("experiment")["err_m"].quantile(0.9))
    return float(np.quantile(e["err_m"], 0.9)), {**s, "side": metrics.interval_side(s["lo"], s["hi"], 4.0)}


def _p90_text(pooled: float, s: dict) -> str:
    per = (f"[{s['lo']:.2f}, {s['hi']:.2f}]" if s["side"] != "none" else "(no interval)")
    return f"{pooled:.2f} m; per experiment (n = {s['n']}) {s['mean']:.2f} m {per}"


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
    """The claims of notebook 02, one row each (:data:`COLUMNS`), each decided by an interval.

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

    def add(claim, paper, ours, rule, verdict, assumption="—"):
        rows.append({"claim": claim, "paper": paper, "paper kind": "—" if paper == "—" else "input", "ours": ours,
                     "ours kind": "reproduced", "assumption": assumption, "rule": rule, "verdict": verdict})

    syn_a = assumption(tour)
    geo = "known mount height" if dim == 2 else "3-D, no height"
    ranks = rankings(syn, lias, seed=seed) if ranks is None else ranks
    paper_order = " < ".join(LABELS[h] for h in PAPER_RANKING)

    def ranked(r: Ranking, what: str = "stops") -> tuple[str, str]:
        """A ranking row's text and verdict: the paper's steps decide; every pair gives the ranks."""
        _, verdict = _decide(list(r.pairs[:max(len(r.rank) - 1, 0)]), "as in the paper", "differs")
        text = _decide(list(r.pairs), "", "", what)[0]
        return text + (f"; rank (tied where not resolved): {r.text()}" if len(r.rank) else ""), verdict

    text, verdict = ranked(ranks["synthetic"])
    add(f"ranking of the heuristics by median stop error, synthetic ({geo})", paper_order, text,
        "each experiment's series of stops one block; " + _RANK_RULE, verdict, syn_a)
    track = syn.track
    if {"residual", POINT} <= set(track["heuristic"]):
        d = paired(track, "residual", POINT, ["experiment", "tag"], blocks="segment", rng=rng)
        cov = track.groupby("heuristic")["err_m"].apply(lambda e: e.notna().mean())
        add("residual pruning (fixed in advance) vs the point-based fixes, median of all distance errors on the "
            "packets both covered (m)", "a slight improvement", _pair_text(d, "packets", 2)
            + f"; coverage {100 * cov['residual']:.0f} %, {100 * cov[POINT]:.0f} %",
            _PAIRED_RULE + " (each experiment and node one block)", _NLS[d["side"]], syn_a)
    if "residual" in set(track["heuristic"]):
        pooled, s = _p90(track[track["heuristic"] == "residual"])
        add("residual pruning: 90 % of all distance errors under 4 m", "yes (the paper's cafeteria)",
            _p90_text(pooled, s), _SEEDS_RULE, _UNDER[s["side"]], syn_a)
    if excess is not None and len(excess):
        p = {m: _p90(t) for m, t in excess.groupby("nlos_mean_m")}
        sides = [s["side"] for _, s in p.values()]
        add("residual pruning: 90 % of all distance errors under 4 m, as the simulated NLOS excess is scaled",
            "yes (the paper's cafeteria)", " / ".join(f"{m:g} m: {_p90_text(*v)}" for m, v in p.items()),
            _SEEDS_RULE + ", at each mean excess", _EXCESS.get(frozenset(sides), "not resolved"),
            f"nlos_mean_m scaled, the rest as above: {_OURS}")
    if other is not None:
        three_d, known = (other, syn) if dim == 2 else (syn, other)
        present = set(three_d.stops["heuristic"])
        flat = ranks["synthetic"] if dim == 2 else ranking(known.stops, ["experiment", "tag"], rng=rng)
        up = ranking(three_d.stops.assign(err_m=three_d.stops["err_3d_m"]), ["experiment", "tag"], rng=rng)
        text, verdict = _same_order(flat, up)
        add("the known-height ranking in 3-D without a height, by 3-D median error (the robust mean has no 3-D "
            "version)", "—", f"known height: rank {flat.text()}; 3-D: {text}", "each order by the ranking rule "
            "(each experiment's stops one block; 3-D: the 3-D error): every pair of the heuristics in both resolved "
            "in both and the same, same; one resolved the other way, changes; else not resolved", verdict, syn_a)
        if "percentile" in present:
            dz = three_d.stops[three_d.stops["heuristic"] == "percentile"]
            d = paired(pd.concat([dz, dz.assign(heuristic="0", err_z_m=0.0)]), "percentile", "0",
                       ["experiment", "tag"], at="segment", column="err_z_m", blocks="segment", rng=rng)
            add("5th percentile in 3-D: median height error (m; > 0: the node sits too high)", "—",
                f"{d['diff_m']:+.2f} {_iv(d)} ({d['n']} stops)", _PAIRED_RULE + " (each experiment's stops one block)",
                _sides("too low", "too high")[d["side"]], syn_a)
    if persistence is not None and persistence["nlos_dwell_s"].nunique() >= 2:
        dwell = sorted(persistence["nlos_dwell_s"].unique())
        base, long = (3.0 if 3.0 in dwell else dwell[0]), dwell[-1]
        at = {w: persistence[persistence["nlos_dwell_s"] == w] for w in (base, long)}
        three = [h for h in PAPER_RANKING if h in set(persistence["heuristic"])]
        first = ranking(at[base], ["experiment", "tag"], rng=rng)       # best at the base: ranked alone first
        top = list(first.rank.index[first.rank == 1])
        text, verdict = _decide([paired(at[long], top[0], h, ["experiment", "tag"], at="segment", blocks="segment",
                                        rng=rng) for h in three if h != top[0]], "same", "changes")
        if len(top) > 1:
            verdict = "no interval" if all(d["side"] == "none" for d in first.pairs) else "not resolved"
        add(f"the best heuristic at {base:g} s NLOS episodes ({', '.join(LABELS[h] for h in top)}"
            f"{'' if len(top) == 1 else ': tied'}) still best at {long:g} s", "—",
            f"{base:g} s: rank (tied where not resolved) {first.text()}; {long:g} s: {text}",
            f"best at {base:g} s: ranked alone first there (the ranking row's rank rule); then the 95 % bootstrap "
            f"interval of its median difference to each other heuristic at {long:g} s (each experiment's stops one "
            "block): all below 0 same, one above 0 changes", verdict, f"nlos_dwell_s varied, the rest as above: {_OURS}")
    for k in (lias.runs if lias is not None else ()):
        if len(ranks[k].rank) >= 2:
            text, verdict = ranked(ranks[k], "poses")
            add(f"LIAS static, {k} ranges: the heuristics ranked by median pose error", paper_order, text,
                "each pose one block; " + _RANK_RULE, verdict)
    pairs = []                              # (claim, paired difference, what is counted, rule, verdicts)
    for k, run in (lias.runs.items() if lias is not None else ()):
        pairs.append((f"LIAS static, {k} ranges: plain NLS (fixed in advance) vs point fixes, median error on common "
                      "epochs (m)", paired(run.epochs, "none", POINT, ["recording", "tag"], blocks="segment", rng=rng),
                      "epochs", " (each pose one block)", _NLS))
    if lias is not None and "calibrated (LOSO)" in lias.runs:
        poses = pd.concat([lias.runs["calibrated (LOSO)"].poses.query("heuristic == 'none'").assign(heuristic="calibrated"),
                           lias.runs["raw"].poses.query("heuristic == 'residual'")])
        pairs.append(("LIAS static: range calibration (plain NLS) vs residual pruning (raw ranges, fixed in advance), "
                      "median error on the same poses (m)",
                      paired(poses, "calibrated", "residual", ["recording"], at="tag", blocks="segment", rng=rng),
                      "poses", " (each pose one block)", _sides("calibration better", "pruning better")))
    for k, run in (lias_dyn.runs.items() if lias_dyn is not None else ()):
        pairs += [(f"LIAS dynamic, {k} ranges: residual pruning (fixed in advance) vs plain NLS, median error on "
                   "common epochs (m)", paired(run.epochs, "residual", "none", ["segment", "tag"], rng=rng), "epochs",
                   "", _sides("residual pruning better", "plain NLS better")),
                  (f"LIAS dynamic, {k} ranges: plain NLS (fixed in advance) vs point fixes, median error on common "
                   "epochs (m)", paired(run.epochs, "none", POINT, ["segment", "tag"], rng=rng), "epochs", "", _NLS)]
    if hanyang is not None and {"LOS", "NLOS"} <= set(hanyang["condition"]):
        pairs.append(("Hanyang static: NLOS − LOS median range error, files paired by height and range (m)",
                      paired(hanyang, "NLOS", "LOS", ["height_m"], at="true_range_m", by="condition",
                             column="median_err_m", blocks="segment", rng=rng), "pairs", " (each height one block)",
                      _sides("NLOS smaller", "NLOS larger")))
    for claim, d, what, blocks, words in pairs:
        add(claim, "—", _pair_text(d, what), _PAIRED_RULE + blocks, words[d["side"]])
    return pd.DataFrame(rows, columns=COLUMNS)


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
