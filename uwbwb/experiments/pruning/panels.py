"""Back ends of notebook 02's panels (cached; they also run headless).

:class:`TourExplorer` serves the synthetic-tour panel (the run's own settings from its results,
other retention/dropout values re-solved, cached); :class:`PieceExplorer` one straight piece of
the LIAS dynamic run. :func:`tour_panel` and :func:`piece_panel` build the panels with options
the data has.
"""

from __future__ import annotations

import dataclasses
import functools

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from ... import widgets
from ...filters.pruning import PruningConfig
from ...geometry import point_fixes
from ...sim import tours as tours_mod
from ...types import Recording
from .figures import plot_segment_fits
from .real import run_dynamic_segments
from .scoring import LABELS
from .study import SyntheticConfig, SyntheticResult, run_tour

__all__ = ["PieceExplorer", "TourExplorer", "piece_panel", "tour_panel"]


class TourExplorer:
    """Back end of the synthetic-tour panel: cached recomputation from frozen configs.

    The run's own settings are served from its results (no recomputation); other
    retention/dropout values re-solve one tour for one node and heuristic, cached.

    Parameters
    ----------
    result, config
        The notebook's synthetic run and its configuration.
    seed
        Seeds tours the run did not simulate (one generator per tour/pace).
    """

    def __init__(self, result: SyntheticResult, config: SyntheticConfig, *, seed: int):
        self.result, self.config, self.seed = result, config, int(seed)
        self.experiment = functools.lru_cache(maxsize=8)(self._experiment)
        self.rows = functools.lru_cache(maxsize=64)(self._rows)
        self.n_solved = 0            # tours re-solved (not served from the run)

    def _experiment(self, tour: int, pace: str):
        name = f"tour{tour}-{pace}"
        if name in self.result.recordings:
            return self.result.recordings[name]
        paces = tuple(dict(self.config.tour.speed_mps))
        return tours_mod.simulate_tour(dataclasses.replace(self.config.tour, tour=tour, pace=pace),
                                       rng=np.random.default_rng((self.seed, tour, paces.index(pace))))

    def _rows(self, tour, pace, node, heuristic, res_retention, res_dropout_pct, rm_retention, rm_dropout_pct):
        base = self.config.pruning
        cfg = dataclasses.replace(base, res_retention=res_retention, res_dropout=res_dropout_pct / 100,
                                  rm_retention=rm_retention, rm_dropout=rm_dropout_pct / 100)
        name = f"tour{tour}-{pace}"
        same = {"residual": ("res_retention", "res_dropout"),
                "robust_mean": ("rm_retention", "rm_dropout")}.get(heuristic, ())
        if (all(np.isclose(getattr(cfg, k), getattr(base, k)) for k in same) and name in self.result.recordings
                and node in self.config.tags and heuristic in self.config.heuristics):
            def pick(d):
                return d[(d.experiment == name) & (d.tag == node) & (d.heuristic == heuristic)]
            return pick(self.result.stops), pick(self.result.moves)
        rec, truth = self.experiment(tour, pace)
        self.n_solved += 1
        c = dataclasses.replace(self.config, pruning=cfg, point_baseline=False)
        s, m, _ = run_tour(rec, truth, c, tags=[node], heuristics=[heuristic])
        return pd.DataFrame(s), pd.DataFrame(m)

    def render(self, heuristic, res_retention, res_dropout_pct, rm_retention, rm_dropout_pct, tour, pace, node):
        """Figure (Fig 9 style) and readout (stop errors, walk velocity and speed ratio) for the panel's values."""
        st, mv = self.rows(tour, pace, node, heuristic, res_retention, res_dropout_pct, rm_retention,
                           rm_dropout_pct)
        rec, _ = self.experiment(tour, pace)
        fig, ax = plt.subplots(figsize=(7.5, 4.8))
        empty = self.result.moves.iloc[:0] if len(self.result.moves) else pd.DataFrame(columns=["heuristic", "t0_s"])
        plot_segment_fits(mv if len(mv) else empty, st, ax=ax, truth_xy=rec.truth[node].pos_m, anchors=rec.anchors,
                          heuristic=heuristic)
        ax.set_title(f"tour {tour}, {pace}, node {node} ({rec.meta['node_heights_m'][node]} m): {LABELS[heuristic]}")
        out = {"median stop error (m)": st.err_m.median(), "90th pct stop error (m)": st.err_m.quantile(0.9)}
        if len(mv):
            out.update({"median walk velocity error (m/s)": mv.vel_err_mps.median(),
                        "median speed ratio": mv.speed_ratio.median()})
        return fig, out


class PieceExplorer:
    """Back end of the LIAS dynamic panel: one straight piece, cached fits, point fixes for comparison.

    Parameters
    ----------
    rec, segments
        The dynamic recording and its straight pieces.
    heights_m
        Tag mount heights (as in :func:`run_dynamic_segments`).
    config, stride
        Base solver configuration and epoch thinning.
    calibration
        Range calibration for ``ranges="calibrated"`` (None: raw only).
    """

    def __init__(self, rec: Recording, segments: pd.DataFrame, *, heights_m: dict, config: PruningConfig,
                 stride: int, calibration=None):
        self.rec, self.segments, self.heights_m = rec, segments, dict(heights_m)
        self.config, self.stride, self.calibration = config, int(stride), calibration
        self.piece = functools.lru_cache(maxsize=64)(self._piece)

    def _piece(self, segment, tag, heuristic, res_retention, rm_retention, dropout_pct, ranges):
        if ranges == "calibrated" and self.calibration is None:
            raise ValueError("no calibration for this run")
        cfg = dataclasses.replace(self.config, res_retention=res_retention, res_dropout=dropout_pct / 100,
                                  rm_retention=rm_retention, rm_dropout=dropout_pct / 100)
        cal = self.calibration if ranges == "calibrated" else None
        return run_dynamic_segments(self.rec, self.segments.iloc[[segment]], heights_m=self.heights_m, tags=[tag],
                                    heuristics=(heuristic,), config=cfg, stride=self.stride, calibration=cal,
                                    point_baseline=False).pieces

    def render(self, segment, tag, heuristic, res_retention, rm_retention, dropout_pct, ranges):
        """Figure (fit over the per-epoch point fixes and the truth) and readout."""
        row = self.piece(segment, tag, heuristic, res_retention, rm_retention, dropout_pct, ranges)
        s = self.segments.iloc[segment]
        log = self.rec.ranges_of(tag, None if ranges == "raw" else self.calibration)
        log = log.between(s.t_start_s, s.t_end_s)
        fixes = point_fixes(log.range_m, self.rec.anchors, dim=2, z_m=self.heights_m[tag])
        fig, ax = plt.subplots(figsize=(6.5, 4.8))
        ax.plot(fixes[:, 0], fixes[:, 1], ".", ms=2, color="#9e9e9e", label="per-epoch point fixes")
        truth_piece = self.rec.truth[tag].between(s.t_start_s, s.t_end_s)
        plot_segment_fits(row, ax=ax, truth_xy=truth_piece.pos_m, anchors=self.rec.anchors, heuristic=heuristic)
        ax.set_title(f"{self.rec.label}, piece {segment} ({s.duration_s:.1f} s), tag {tag}, {ranges}")
        if row.empty:
            return fig, {"fit": "too few ranges in this piece"}
        r = row.iloc[0]
        return fig, {"start error (m)": r.start_err_m, "mean error (m)": r.mean_err_m,
                     "velocity error (m/s)": r.vel_err_mps, "speed ratio": r.speed_ratio,
                     "true speed (m/s)": float(np.hypot(r.true_vx_mps, r.true_vy_mps))}


def tour_panel(explorer: TourExplorer, *, res_retention: float, rm_retention: float) -> widgets.Panel:
    """The synthetic-tour panel: heuristics of the run, every tour, pace and node of the rig (tours the
    run did not simulate are simulated on demand), retention and dropout of the two pruning heuristics."""
    cfg = explorer.config
    tour = 2 if 2 in cfg.tours else cfg.tours[-1]
    return widgets.Panel("Synthetic tours: heuristic and its parameters", {
        "heuristic": widgets.dropdown("heuristic", {LABELS[h]: h for h in cfg.heuristics}, "residual"),
        "res_retention": widgets.float_slider("residual pruning: retention", res_retention, 0.5, 1.0, 0.05),
        "res_dropout_pct": widgets.float_slider("residual pruning: dropout step", 0.5, 0.25, 5.0, 0.25, unit="%"),
        "rm_retention": widgets.float_slider("robust mean: retention", rm_retention, 0.1, 1.0, 0.05),
        "rm_dropout_pct": widgets.float_slider("robust mean: dropout step", 1.0, 0.25, 5.0, 0.25, unit="%"),
        "tour": widgets.dropdown("tour", list(tours_mod.TOURS), tour),
        "pace": widgets.dropdown("pace", list(dict(cfg.tour.speed_mps)), cfg.paces[-1]),
        "node": widgets.dropdown("node (height)", {f"{k} ({v} m)": k for k, v in cfg.tour.node_heights_m},
                                 cfg.tags[-1]),
    }, explorer.render)


def piece_panel(explorer: PieceExplorer, *, tags, res_retention: float, rm_retention: float) -> widgets.Panel:
    """The LIAS dynamic panel: the run's straight pieces and tags, the heuristics that apply to motion,
    and the range options the run has (calibrated only when a calibration was fitted)."""
    tags = list(tags)
    return widgets.Panel("LIAS dynamic run: one straight piece", {
        "segment": widgets.int_slider("piece", 0, 0, len(explorer.segments) - 1),
        "tag": widgets.dropdown("tag", tags, tags[0]),
        "heuristic": widgets.dropdown("heuristic", {LABELS[h]: h for h in ("none", "robust_mean", "residual")},
                                      "residual"),
        "res_retention": widgets.float_slider("residual pruning: retention", res_retention, 0.5, 1.0, 0.05),
        "rm_retention": widgets.float_slider("robust mean: retention", rm_retention, 0.1, 1.0, 0.05),
        "dropout_pct": widgets.float_slider("dropout step", 0.5, 0.25, 5.0, 0.25, unit="%"),
        "ranges": widgets.dropdown("ranges", ["raw", "calibrated"][:1 + (explorer.calibration is not None)], "raw"),
    }, explorer.render)
