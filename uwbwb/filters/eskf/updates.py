"""UWB measurement models of the error-state filters: TDoAs (with the eq-4 test and a snapshot fix) and ranges."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ... import validate
from ...models.ins import N_ERR, P_, TH_, _skew3
from ...models.tdoa import TdoaModel, triangle_outliers
from ...types import TdoaLog
from ..ekf import Linearisation
from ..tdoa_ls import tdoa_least_squares
from .common import SNAPSHOT_RMS_SIGMAS


# ====================================================================== measurement models
def _tag_jacobian(C: np.ndarray, lever_m: np.ndarray) -> np.ndarray:
    """``∂(p + C l)/∂δx``, shape ``(3, 15)``: identity on δp, ``−[C l ×]`` on δθ."""
    J = np.zeros((3, N_ERR))
    J[:, P_] = np.eye(3)
    J[:, TH_] = -_skew3(C @ lever_m)
    return J


@dataclass(frozen=True)
class TdoaUpdate:
    """Raw TDoAs as error-state measurements (plus the eq-4 test).

    Attributes
    ----------
    model
        TDoA model with ``dim=3`` (anchors, per-anchor range σ, reference correlation).
    outlier_c_m
        ``C`` of eq. (4), metres; None disables the test.
    """

    model: TdoaModel
    outlier_c_m: float | None = 0.1

    def __post_init__(self):
        if not isinstance(self.model, TdoaModel):
            raise ValueError(f"TdoaUpdate.model must be a TdoaModel, got {type(self.model).__name__}")
        if self.outlier_c_m is not None:
            validate.number("TdoaUpdate.outlier_c_m", self.outlier_c_m, minimum=0.0, strict_minimum=True)
        if self.model.dim != 3:
            raise ValueError("TdoaUpdate needs a 3-D TdoaModel (the INS state is 3-D; a known height is a "
                             "separate pseudo-measurement)")

    def screen(self, tdoa_m: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The eq-4 test over a whole log: TDoAs with the rejected ones set to NaN, and the
        number rejected per epoch."""
        d = np.array(tdoa_m, float)
        if self.outlier_c_m is None:
            return d, np.zeros(d.shape[0], int)
        bad = triangle_outliers(d, ref, self.model.anchor_pos_m, self.outlier_c_m)
        d[bad] = np.nan
        return d, bad.sum(axis=1)

    def snapshot(self, t_s: np.ndarray, tdoa_m: np.ndarray, ref: np.ndarray) -> np.ndarray:
        """Each epoch's own TDoA least-squares fix (started at the anchors' centroid, no prior),
        ``(T, 3)``, m; NaN where there is none or it is inconsistent: not converged, or a
        residual RMS above :data:`SNAPSHOT_RMS_SIGMAS` TDoA σ (``√2`` times the median range σ).

        :class:`TightEskf` starts its iterated update there when the prior is far off (after an
        outage), instead of linearising at a prior metres away."""
        d = np.array(tdoa_m, float)
        r = np.array(ref, int)
        lone = (r >= 0) & (np.isfinite(d).sum(axis=1) < 2)   # the eq-4 test left the reference alone
        d[lone], r[lone] = np.nan, -1
        ids = tuple(str(j) for j in range(d.shape[1]))
        ls = tdoa_least_squares(TdoaLog(np.asarray(t_s, float), d, r, ids), self.model)
        limit = SNAPSHOT_RMS_SIGMAS * math.sqrt(2.0) * float(np.median(self.model.sigma_m))
        good = (ls.status == 0) & (ls.residual_rms_m <= limit) & np.all(np.isfinite(ls.pos_m), axis=1)
        return np.where(good[:, None], ls.pos_m, np.nan)

    def linearise(self, tag_pos_m, J_tag, row, ref) -> Linearisation | None:
        """Linearisation of one epoch's (screened) TDoAs at the tag position."""
        if ref < 0 or np.isfinite(row).sum() < 2:
            return None
        z, h, H_pos, R, _ = self.model.epoch(row, tag_pos_m, int(ref))
        return Linearisation(z, h, H_pos @ J_tag, R)


@dataclass(frozen=True)
class RangeUpdate:
    """Ranges (two-way, independent noise) as error-state measurements.

    Attributes
    ----------
    anchor_pos_m
        ``(n_anchors, 3)``, m.
    sigma_m
        Range noise SD, scalar or per anchor, m.
    bias_m
        Common range bias subtracted from every range, m.
    """

    anchor_pos_m: np.ndarray
    sigma_m: np.ndarray | float = 0.1
    bias_m: float = 0.0

    def __post_init__(self):
        a = np.array(self.anchor_pos_m, float)
        if a.ndim != 2 or a.shape[1] != 3:
            raise ValueError(f"RangeUpdate.anchor_pos_m must be (n, 3), got {a.shape}")
        s = np.broadcast_to(np.array(self.sigma_m, float), (a.shape[0],)).copy()
        if not np.all(np.isfinite(a)):
            raise ValueError("RangeUpdate.anchor_pos_m must be finite")
        if np.any(~(s > 0)) or not np.all(np.isfinite(s)):
            raise ValueError(f"RangeUpdate.sigma_m must be positive and finite, got {self.sigma_m!r}")
        validate.number("RangeUpdate.bias_m", self.bias_m)
        object.__setattr__(self, "anchor_pos_m", a)
        object.__setattr__(self, "sigma_m", s)

    def screen(self, range_m: np.ndarray, ref=None) -> tuple[np.ndarray, np.ndarray]:
        """Ranges have no eq-4 test: returned unchanged, zero rejections."""
        return np.asarray(range_m, float), np.zeros(len(range_m), int)

    def linearise(self, tag_pos_m, J_tag, row, ref=None) -> Linearisation | None:
        ok = np.flatnonzero(np.isfinite(row))
        if ok.size == 0:
            return None
        d = tag_pos_m - self.anchor_pos_m[ok]
        r = np.sqrt(np.einsum("ij,ij->i", d, d))
        u = d / np.maximum(r, 1e-9)[:, None]
        return Linearisation(row[ok] - self.bias_m, r, u @ J_tag, np.diag(self.sigma_m[ok] ** 2))
