"""The comparison with paper 003, written from the run's own numbers (notebook 04)."""

from __future__ import annotations

import numpy as np

from .study import PAPER

__all__ = ["discussion_markdown"]


def _pct(x: float) -> str:
    return "—" if not np.isfinite(x) else f"{x:.2g} %"


def discussion_markdown(*, fast: bool, dp_ref_ms: dict, fractions: dict, geometry: dict, fisher: dict,
                        headline: dict, scores, brute_small: dict) -> str:
    """Markdown discussion.

    Parameters
    ----------
    dp_ref_ms
        ``{"model": (b0, b7), "P=0.5": (b0, b7), "P7_ms": period of beacon 7}`` in ms.
    fractions
        ``{layout: {"conditional": FractionEstimate, "brute force": ..., "ranges": ...}}`` at 15 cm.
    geometry
        :func:`~.study.ghost_geometry` of the cubic ghosts under 8 cm.
    fisher
        :func:`~.study.fisher_analysis` at the reference (cubic).
    headline
        ``{variant: TrackStudy.headline(variant)}``.
    scores
        :func:`~.study.filter_scores` table.
    brute_small
        ``{"n": draws, "hits_4cm": …, "hits_6cm": …}`` of the cubic brute-force run.
    """
    c, lab = fractions["cubic"], fractions["lab"]
    weak = fisher["weak"][0]
    mean = scores.groupby("variant")[["PF CEP50 (cm)", "MH-EKF CEP50 (cm)"]].mean()
    d, r = headline["Doppler"], headline["Doppler + ranges"]
    lines = []
    if fast:
        lines.append("> **FAST mode: every number below is a smoke test** (few samples, few runs); "
                     "the statements are written from them all the same, so read them with that in mind.\n")
    lines += [
        "### Differences from the paper, and why",
        f"* **ΔP_ref.** Eq 1 at the reference pair gives {dp_ref_ms['P=0.5'][0]:.2f} ms (beacon 0) and "
        f"{dp_ref_ms['P=0.5'][1]:.2f} ms (beacon 7) with P = 500 ms; the paper prints 1.1 ms and −1.2 ms. Beacon 0 "
        f"agrees to the printed precision; beacon 7 does not (the known defect of the text). With this workbench's "
        f"per-beacon periods (beacon 7 at {dp_ref_ms['P7_ms']:.0f} ms) it is {dp_ref_ms['model'][1]:.2f} ms: the paper's value would "
        "need a period near 0.55 s, which it does not state.",
        f"* **Fraction under 15 cm, cubic.** {_pct(100 * c['conditional'].fraction)} "
        f"[{_pct(100 * c['conditional'].ci_low)}, {_pct(100 * c['conditional'].ci_high)}] (conditional estimator; "
        f"brute force {_pct(100 * c['brute force'].fraction)} from {c['brute force'].n_draws:.2g} draws) against the "
        f"paper's \"less than 0.0005 %\". "
        + ("This agrees: the paper's bound sits at the edge of the interval, so its \"less than\" reads as a rounded "
           "estimate of the same quantity." if c["conditional"].ci_low <= 5e-6 * 1.1 else
           "This is above the paper's bound; with v_s, the periods and the box as stated, eq 1 leaves this much "
           "volume under 15 cm."),
        f"* **Fraction under 15 cm, lab.** {_pct(100 * lab['conditional'].fraction)} against the paper's "
        "0.0186 %. The paper gives no coordinates for its lab; ours is a reconstruction (walls and ceiling, "
        "0.4 m of z spread), so only the order of magnitude and the direction of the change are comparable: the "
        f"flat layout leaves {lab['conditional'].fraction / c['conditional'].fraction:.0f}× more of the space under "
        "15 cm than the cube (paper: 37×).",
        f"* **Figs 3–4 at small thresholds.** Brute force with {brute_small['n']:.2g} uniform draws finds "
        f"{brute_small['hits_4cm']} pairs under 4 cm and {brute_small['hits_6cm']} under 6 cm (cubic): the paper's "
        "dense clouds under 2 and 4 cm cannot come from plain uniform sampling of the stated box at any size it "
        "could have run. Our clouds are drawn from the conditional sampler (points resampled ∝ weight, i.e. the "
        "uniform density restricted to the ghost set), so they show where the set is, not how many draws hit it.",
        f"* **Shape of the ghost set.** The positions under 8 cm lie on a plane whose normal is "
        f"{geometry['angle(position plane normal, V) (°)']:.0f}° from V_ref (thickness/extent "
        f"{geometry['position plane normal: spread ratio']:.2f}), and the velocities spread along an axis "
        f"{geometry['angle(velocity main axis, V) (°)']:.0f}° from V_ref: the paper's two observations hold. The "
        f"weakest direction of the information matrix at the reference moves the position at "
        f"{weak['angle(position part, V) (°)']:.0f}° to V and the velocity at "
        f"{weak['angle(velocity part, ±V) (°)']:.0f}° to ±V.",
        f"* **Fig 6, PF on the simulated rectangle.** CEP50 of the snapshot clouds {d['cep50_cm']:.0f} cm (paper: "
        f"about 25 cm); error along the direction of travel / across it {d['along_over_cross']:.2f} (paper: about "
        "0.5). The paper's numbers come from its real recording; ours from a simulation with the paper's "
        "1–2 cm of timing noise and assumed miss and spurious rates, so agreement in CEP50 is a consistency check "
        "of the method, not of the hardware. The along/across ratio varies from corner to corner in our runs "
        "(see the table): the \"half\" of the paper is one corner of one recording.",
        f"* **Kalman vs particle filter.** Averaged over {scores['recording'].nunique()} simulated recording(s) and "
        f"the same scored epochs, Doppler only: PF {mean.loc['Doppler', 'PF CEP50 (cm)']:.0f} cm, MH-EKF "
        f"{mean.loc['Doppler', 'MH-EKF CEP50 (cm)']:.0f} cm. "
        + ("The paper's speculation that the Kalman filter does worse is not borne out here: given the same room "
           "prior, the SCAAT EKF with multiple hypotheses is as accurate as the PF." if
           mean.loc['Doppler', 'MH-EKF CEP50 (cm)'] <= 1.15 * mean.loc['Doppler', 'PF CEP50 (cm)'] else
           "The MH-EKF is worse than the PF, as the paper speculates."),
        f"* **The ranging term (section 5).** With pseudo-ranges from a known beacon-clock model the fraction "
        f"under 15 cm drops to {_pct(100 * c['ranges'].fraction)} (cubic) and {_pct(100 * lab['ranges'].fraction)} "
        f"(lab), and the PF's snapshot CEP50 to {r['cep50_cm']:.0f} cm (MH-EKF on all epochs: "
        f"{mean.loc['Doppler + ranges', 'MH-EKF CEP50 (cm)']:.0f} cm). The clock model is assumed exact, so this "
        "is an upper bound on what the proposal can give; a real clock model has to be learnt while tracking.",
    ]
    return "\n".join(lines)
