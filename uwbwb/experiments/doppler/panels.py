"""Back ends of notebook 04's widgets (cached; they also run headless).

:func:`space_panel` reruns the conditional sampler for a layout, threshold and reference
velocity; :func:`filter_panel` reruns one filter on the first recording of Fig 6. Each
returns a :class:`uwbwb.widgets.Panel` whose callback recomputes from frozen settings
(cached per setting) and redraws one :class:`uwbwb.widgets.PanelFigure`.
"""

from __future__ import annotations

import functools

import numpy as np

from ... import metrics, widgets
from ... import sampling as smp
from ...filters import doppler as fd
from ...models import doppler as dm
from ...plotting import color_for
from . import figures, study

__all__ = ["ghost_map", "space_panel", "filter_panel"]


@functools.lru_cache(maxsize=32)
def ghost_map(cfg: study.StudyConfig, layout: str, threshold_cm: float, speed_scale: float, turn_deg: float,
              n_positions: int):
    """Conditional sampler for ``threshold_cm`` at ``V_ref`` scaled by ``speed_scale`` and turned by ``turn_deg``
    in x–y: ``(model, v_ref, SamplerResult)``."""
    model = study.make_model(layout, cfg)
    a = np.radians(turn_deg)
    rot = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    v_ref = speed_scale * rot @ dm.REFERENCE_VEL_MPS
    res = smp.conditional(model, dm.REFERENCE_POS_M, v_ref, int(n_positions), seed=cfg.seed,
                          thresholds_m=(threshold_cm / 100,), workers=1)
    return model, v_ref, res


def space_panel(cfg: study.StudyConfig):
    """Widget: ghost solutions of eq 1 (distinct samples, never resampled) and the fraction with its interval."""
    view = widgets.PanelFigure(1, 2, figsize=(9, 4.3))

    def render(layout, threshold_cm, speed_scale, turn_deg, n_positions):
        model, v_ref, res = ghost_map(cfg, layout, threshold_cm, speed_scale, turn_deg, n_positions)
        s = res.samples
        axes = view.clear()
        figures.ghost_panel(s, "position", beacons=model.beacons.pos_m, ax=axes[0])
        figures.ghost_panel(s, "velocity", ax=axes[1])
        axes[1].plot(v_ref[0], v_ref[1], "o", markerfacecolor="none", markeredgecolor="#d62728", markersize=12)
        n_s, n_p = study.distinct_counts(s)
        fig = view.done()
        e = res.estimates[0]
        return fig, {"fraction under threshold (%)": 100 * e.fraction, "95 % low (%)": 100 * e.ci_low,
                     "95 % high (%)": 100 * e.ci_high, "distinct samples shown": n_s, "distinct positions": n_p,
                     "positions drawn": e.n_positions, "exact δ evaluations": e.n_draws,
                     "|V_ref| (m/s)": float(np.linalg.norm(v_ref))}

    return widgets.Panel("Ghost solutions of eq 1 (conditional sampler)", {
        "layout": widgets.dropdown("layout", ["cubic", "lab"], "cubic"),
        "threshold_cm": widgets.float_slider("δ threshold", 8.0, 2.0, 15.0, 1.0, unit="cm"),
        "speed_scale": widgets.float_slider("|V| / |V_ref|", 1.0, 0.25, 3.0, 0.25),
        "turn_deg": widgets.float_slider("V turned in x–y by", 0.0, -180.0, 180.0, 15.0, unit="°"),
        "n_positions": widgets.dropdown("positions sampled", {"10 000": 10_000, "30 000": 30_000}, 10_000),
    }, render)


def filter_panel(track: study.TrackStudy, cfg: study.StudyConfig, *, layout: str = "lab"):
    """Widget: the PF (one run) or the MH-EKF on ``track``'s recording, with or without pseudo-ranges."""

    @functools.lru_cache(maxsize=32)
    def run(method, n_particles, sigma_xy, ranges):
        model, log = track.model, track.log
        r = fd.clock_pseudo_ranges(log, model, track.recording.phase_s) if ranges else None
        motion = dm.ReceiverMotion((sigma_xy, sigma_xy, 0.2))
        if method == "PF":
            lo, hi = study.ROOMS[layout]
            pf = fd.DopplerPf(model, motion, n_particles=int(n_particles), room_lo_m=lo, room_hi_m=hi)
            return pf.run(log, n_runs=1, rng=np.random.default_rng(cfg.seed), ranges_m=r).estimates(0)
        key = "Doppler + ranges" if ranges else "Doppler"
        if sigma_xy == 2.0 and key in track.kf:          # the run of the notebook, already computed
            return track.kf[key]
        kf = fd.ScaatMhEkf(model, motion, p_detect=1 - cfg.p_miss, spurious_rate_hz=max(cfg.spurious_rate_hz, 1e-3))
        return kf.run(log, study.kf_prior(layout), ranges_m=r)

    view = widgets.PanelFigure(1, 2, figsize=(11, 4.2))

    def render(method, n_particles, sigma_xy, ranges):
        est = run(method, n_particles, sigma_xy, ranges)
        truth = track.track.pos_m(est.t_s)
        err = np.linalg.norm(est.pos_m[:, :2] - truth[:, :2], axis=1)
        late = est.t_s > track.t_score_s
        axes = view.clear()
        lap = track.track.pos_m(np.linspace(0, track.track.length_m / track.track.speed_mps, 300))
        axes[0].plot(lap[:, 0], lap[:, 1], color="#000000", linewidth=1.0, label="truth")
        axes[0].plot(est.pos_m[late, 0], est.pos_m[late, 1], color=color_for("PF" if method == "PF" else "MH-EKF"),
                     label=method)
        axes[0].set_aspect("equal")
        axes[0].legend(fontsize=8)
        axes[1].plot(est.t_s, 100 * err, color="#636363")
        axes[1].set_xlabel("t (s)")
        axes[1].set_ylabel("horizontal error (cm)")
        return view.done(), {"CEP50 after the start-up (cm)": 100 * metrics.cep50(err[late]),
                             "CEP95 after the start-up (cm)": 100 * metrics.cep95(err[late]),
                             "epochs": int(late.sum())}

    return widgets.Panel("Doppler filters on the Fig 6 recording", {
        "n_particles": widgets.int_slider("PF particles", 400, 200, 1000, 200),
        "method": widgets.dropdown("filter", {"particle filter": "PF", "SCAAT MH-EKF": "MH-EKF"}, "PF"),
        "sigma_xy": widgets.float_slider("acceleration σ (x, y)", 2.0, 0.5, 4.0, 0.5, unit="m/s²"),
        "ranges": widgets.dropdown("measurements", {"Doppler only": False, "Doppler + pseudo-ranges": True}, False),
    }, render)
