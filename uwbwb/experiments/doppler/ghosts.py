"""Why the ghosts of paper 003 lie on a plane: the shape of a ghost cloud and the weak directions of eq 1.

Notebook 04, section 3 (and Fig 5's cuts): :func:`band_direction` (Fig 3d's diagonal band), :func:`cuts`
(δ along a line through the reference pair), :func:`fisher_analysis` (the Jacobian's weak directions) and
:func:`ghost_geometry` (the plane normal and the velocity axis of a cloud, each against ``V_ref``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ... import sampling as smp
from ...models import doppler as dm

__all__ = ["band_direction", "cuts", "fisher_analysis", "ghost_geometry"]


def _principal_axes(pts: np.ndarray, weight: np.ndarray):
    """Eigenvalues (ascending) and axes (columns) of the weighted covariance of ``pts``."""
    w = weight / weight.sum()
    c = pts - w @ pts
    return np.linalg.eigh(c.T @ (c * w[:, None]))


def band_direction(samples: smp.GhostSamples) -> np.ndarray:
    """Unit x–y direction of the longest axis of the (weighted) position cloud (Fig 3d's diagonal band)."""
    d = _principal_axes(samples.pos_m[:, :2], samples.weight)[1][:, -1]
    return np.array([d[0], d[1], 0.0]) * (1 if d[0] >= 0 else -1)


def cuts(model: dm.DopplerModel, direction, velocities: dict[str, np.ndarray], s_m: np.ndarray) -> pd.DataFrame:
    """Fig 5: δ (cm) along ``X_ref + s · direction`` for fixed velocities."""
    X = dm.REFERENCE_POS_M + np.outer(s_m, direction)
    ref = model.delta_p(dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS)
    out = {"s (m)": s_m}
    for name, v in velocities.items():
        out[name] = 100 * model.distance_m(model.delta_p(X, np.broadcast_to(v, X.shape)), ref)
    return pd.DataFrame(out)


def fisher_analysis(model: dm.DopplerModel) -> dict:
    """Jacobian of ``v_s ΔP`` at the reference pair and the weak directions of its information matrix.

    Returns the singular values (m per unit of state) and, for the two weakest
    directions, the angle (degrees) between the direction's position part and
    ``V_ref`` and between its velocity part and ``V_ref``.
    """
    X, V = dm.REFERENCE_POS_M, dm.REFERENCE_VEL_MPS
    J = model.v_s_mps * model.jacobian(X, V)                     # (n, 6), metres per (m | m/s)
    _, s, vt = np.linalg.svd(J)
    v_hat = V / np.linalg.norm(V)
    rows = []
    for k in (5, 4):
        d = vt[k]
        rows.append({"singular value": s[k], "position part": d[:3], "velocity part": d[3:],
                     "|position part|": np.linalg.norm(d[:3]),
                     "angle(position part, V) (°)": _angle(d[:3], v_hat),
                     "angle(velocity part, ±V) (°)": min(_angle(d[3:], v_hat), _angle(-d[3:], v_hat))})
    return {"J": J, "singular_values": s, "weak": rows}


def _angle(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.degrees(np.arccos(np.clip(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)), -1, 1))))


def ghost_geometry(samples: smp.GhostSamples) -> dict:
    """Shape of a ghost cloud: the normal of the plane the positions lie on (smallest principal axis)
    and the main axis of the velocities, each with its angle to ``V_ref`` (degrees)."""
    v_hat = dm.REFERENCE_VEL_MPS / np.linalg.norm(dm.REFERENCE_VEL_MPS)
    out = {}
    for name, pts, axis in (("position plane normal", samples.pos_m, 0), ("velocity main axis", samples.vel_mps, -1)):
        vals, vecs = _principal_axes(pts, samples.weight)
        d = vecs[:, axis]
        out[name] = d
        out[f"angle({name}, V) (°)"] = min(_angle(d, v_hat), _angle(-d, v_hat))
        out[f"{name}: spread ratio"] = float(np.sqrt(vals[0] / vals[-1]))
    return out
