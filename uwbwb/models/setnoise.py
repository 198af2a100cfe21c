"""Sensor-set switching noise: the measurement model of Banerjee, Suski & Hoover (paper 000).

A UWB system such as Ubisense reports a 2-D position computed from a *set* of
sensors that changes from one measurement to the next. Because every sensor's
ranges carry their own systematic error, every set produces its own systematic
position error. The paper models the error of a measurement taken with set ``s``
as an independent Gaussian per axis (its eq. 1 and eq. 6)::

    x̃ = x + N(μx_s, σx_s),    ỹ = y + N(μy_s, σy_s)

This module holds that model and everything that touches it, so the simulator
(:mod:`uwbwb.sim.setnoise`), the calibration and the filters
(:mod:`uwbwb.filters.setnoise`) share one definition:

- the fixes it explains, :class:`uwbwb.types.SetFixLog` (sensor sets as integer bit masks,
  bit ``i`` set ⇔ sensor ``i`` used, with the paper's labels such as ``'76540'``);
- :class:`SetNoiseModel`, the per-set ``(μ, σ)`` table plus the facility-wide
  default (fitted by :func:`uwbwb.calibration.fit_set_noise`, the paper's calibration
  rules of section II-B2), and :func:`log_likelihood`, its eq. 9.

Interpretations of the paper made here (also stated in notebook 01):

- σ is the sample standard deviation (``ddof=1``) of the errors about their mean.
- "weighted-averaged by the number of measurements" is applied literally to all
  four parameters, σ included (not a pooled variance).
- The facility-wide model is the mean and standard deviation of *all*
  calibration errors, whatever their set or location.
- Eq. 9's sign is taken from eq. 6 (see :func:`log_likelihood`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..types import set_label


# --------------------------------------------------------------------------- eq. 9

def log_likelihood(pos_m: np.ndarray, z_m: np.ndarray, mu_m: np.ndarray, sigma_m: np.ndarray,
                   *, normalised: bool = False) -> np.ndarray:
    """Log of the paper's eq. 9: likelihood of fix ``z`` given state positions ``pos``.

    ``log p = −(x + μx − x̃)² / (2σx²) − (y + μy − ỹ)² / (2σy²)``

    Sign: eq. 9 prints ``(x − μx) − x̃``, but the paper defines μ as the mean shift
    of the measurements relative to the truth (section II-B1) and writes
    ``x̃ = x + N(μx, σx)`` (eq. 6); a particle's most probable measurement is then
    ``x + μx``, which is what we use (the printed sign would add the bias twice
    instead of removing it).

    Eq. 9 omits the Gaussian normalising constant; it depends only on the set,
    not on the particle, and cancels when weights are normalised (eq. 10).

    Parameters
    ----------
    pos_m
        Positions ``(x, y)`` to score, shape ``(..., 2)``, metres.
    z_m, mu_m, sigma_m
        Fix, set bias and set standard deviation, each broadcastable to ``pos_m``, metres.
    normalised
        Add ``−log(2π σx σy)``, making it the log of a proper density.

    Returns
    -------
    ndarray, shape ``pos_m.shape[:-1]``
    """
    pos_m, z_m, mu_m, sigma_m = (np.asarray(a) for a in (pos_m, z_m, mu_m, sigma_m))
    r = (pos_m + mu_m - z_m) / sigma_m
    out = -0.5 * np.sum(r * r, axis=-1)
    if normalised:
        out = out - np.log(2 * np.pi * np.prod(sigma_m, axis=-1))
    return out


# --------------------------------------------------------------------------- the model

@dataclass(frozen=True, eq=False)
class SetNoiseModel:
    """Per-set Gaussian fix noise ``N(μx, μy, σx, σy)`` (eq. 1) with a facility-wide default.

    Attributes
    ----------
    set_id
        Modelled sets, shape ``(n_sets,)``, int64 bit masks, sorted ascending.
    mu_m
        Mean error ``(μx, μy)`` per set, shape ``(n_sets, 2)``, metres.
    sigma_m
        Standard deviation ``(σx, σy)`` per set, shape ``(n_sets, 2)``, metres, > 0.
    n
        Calibration measurements behind each set's model, shape ``(n_sets,)``.
    default_mu_m, default_sigma_m
        Facility-wide model used for every set without its own, shape ``(2,)``, metres.
    default_n
        Calibration measurements behind the facility-wide model.
    sensor_ids
        Sensor names, index ``i`` ↔ bit ``i`` of the set ids.
    """

    set_id: np.ndarray
    mu_m: np.ndarray
    sigma_m: np.ndarray
    n: np.ndarray
    default_mu_m: np.ndarray
    default_sigma_m: np.ndarray
    default_n: int = 0
    sensor_ids: tuple[str, ...] = tuple(str(i) for i in range(8))
    meta: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        s = np.array(self.set_id, np.int64).reshape(-1)
        mu = np.array(self.mu_m, float).reshape(-1, 2) if s.size else np.zeros((0, 2))
        sd = np.array(self.sigma_m, float).reshape(-1, 2) if s.size else np.zeros((0, 2))
        n = np.array(self.n, np.int64).reshape(-1)
        dmu = np.array(self.default_mu_m, float)
        dsd = np.array(self.default_sigma_m, float)
        if mu.shape != (s.size, 2) or sd.shape != (s.size, 2) or n.shape != s.shape:
            raise ValueError(f"SetNoiseModel: set_id {s.shape}, mu_m {mu.shape}, sigma_m {sd.shape}, "
                             f"n {n.shape} do not describe the same sets")
        if dmu.shape != (2,) or dsd.shape != (2,):
            raise ValueError("SetNoiseModel: default_mu_m and default_sigma_m must have shape (2,)")
        if np.any(np.diff(s) <= 0):
            raise ValueError("SetNoiseModel.set_id must be unique and sorted ascending")
        if not (np.all(np.isfinite(mu)) and np.all(np.isfinite(dmu))):
            raise ValueError("SetNoiseModel: biases must be finite")
        if not (np.all(sd > 0) and np.all(dsd > 0) and np.all(np.isfinite(sd)) and np.all(np.isfinite(dsd))):
            raise ValueError("SetNoiseModel: standard deviations must be finite and positive")
        for name, arr in (("set_id", s), ("mu_m", mu), ("sigma_m", sd), ("n", n),
                          ("default_mu_m", dmu), ("default_sigma_m", dsd)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "default_n", int(self.default_n))
        object.__setattr__(self, "sensor_ids", tuple(str(i) for i in self.sensor_ids))

    def __len__(self) -> int:
        return self.set_id.size

    # ------------------------------------------------------------------ use
    def lookup(self, set_id) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(μ, σ)`` for each observed set; unmodelled sets get the facility-wide model.

        Parameters
        ----------
        set_id
            Observed sets, any shape ``(...)``.

        Returns
        -------
        mu_m, sigma_m
            Shape ``(..., 2)``, metres.
        modelled
            Shape ``(...)``, bool: True where the set has its own model.
        """
        q = np.asarray(set_id, np.int64)
        mu = np.broadcast_to(self.default_mu_m, q.shape + (2,)).copy()
        sd = np.broadcast_to(self.default_sigma_m, q.shape + (2,)).copy()
        modelled = np.zeros(q.shape, bool)
        if self.set_id.size:
            pos = np.minimum(np.searchsorted(self.set_id, q), self.set_id.size - 1)
            modelled = self.set_id[pos] == q
            mu[modelled] = self.mu_m[pos[modelled]]
            sd[modelled] = self.sigma_m[pos[modelled]]
        return mu, sd, modelled

    def facility_only(self) -> "SetNoiseModel":
        """The same facility-wide model with no per-set entries (the paper's baseline filter)."""
        return SetNoiseModel(np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, np.int64),
                             self.default_mu_m, self.default_sigma_m, self.default_n, self.sensor_ids,
                             {**self.meta, "variant": "facility-wide only"})

    def sample(self, pos_m: np.ndarray, set_id: np.ndarray, *, rng: np.random.Generator) -> np.ndarray:
        """Fixes drawn from the model (eq. 6): ``pos + μ_s + σ_s · N(0, 1)`` per axis.

        Parameters
        ----------
        pos_m
            True positions, shape ``(T, 2)``, metres.
        set_id
            Set of each fix, shape ``(T,)``.

        Returns
        -------
        ndarray, shape ``(T, 2)``, metres.
        """
        mu, sd, _ = self.lookup(set_id)
        return np.asarray(pos_m, float) + mu + sd * rng.standard_normal(mu.shape)

    # ------------------------------------------------------------------ fit
    # ------------------------------------------------------------------ tables
    def to_frame(self) -> pd.DataFrame:
        """One row per modelled set plus a last row ``label='default'`` for the facility-wide model.

        Columns ``set_id, label, n, mu_x_m, mu_y_m, sigma_x_m, sigma_y_m``; the default row
        has ``set_id = 0``.
        """
        rows = pd.DataFrame({"set_id": self.set_id,
                             "label": [set_label(s, self.sensor_ids) for s in self.set_id],
                             "n": self.n, "mu_x_m": self.mu_m[:, 0], "mu_y_m": self.mu_m[:, 1],
                             "sigma_x_m": self.sigma_m[:, 0], "sigma_y_m": self.sigma_m[:, 1]})
        default = pd.DataFrame({"set_id": [0], "label": ["default"], "n": [self.default_n],
                                "mu_x_m": [self.default_mu_m[0]], "mu_y_m": [self.default_mu_m[1]],
                                "sigma_x_m": [self.default_sigma_m[0]], "sigma_y_m": [self.default_sigma_m[1]]})
        return pd.concat([rows.sort_values("n", ascending=False, kind="stable"), default], ignore_index=True)

    @classmethod
    def from_frame(cls, df: pd.DataFrame, sensor_ids=None) -> "SetNoiseModel":
        """Inverse of :meth:`to_frame`."""
        cols = ["set_id", "n", "mu_x_m", "mu_y_m", "sigma_x_m", "sigma_y_m"]
        missing = [c for c in cols if c not in df.columns]
        if missing:
            raise ValueError(f"set-noise table lacks columns {missing}")
        is_default = df["set_id"].to_numpy(np.int64) == 0
        if is_default.sum() != 1:
            raise ValueError("set-noise table needs exactly one facility-wide row (set_id 0)")
        d = df[is_default].iloc[0]
        sets = df[~is_default].sort_values("set_id")
        kw = {} if sensor_ids is None else {"sensor_ids": sensor_ids}
        return cls(sets["set_id"].to_numpy(np.int64), sets[["mu_x_m", "mu_y_m"]].to_numpy(float),
                   sets[["sigma_x_m", "sigma_y_m"]].to_numpy(float), sets["n"].to_numpy(np.int64),
                   [d["mu_x_m"], d["mu_y_m"]], [d["sigma_x_m"], d["sigma_y_m"]], int(d["n"]), **kw)
