"""Position and velocity from Doppler period shifts of independent beacons (paper 003, section 4).

One import path for the whole family (the modules below hold the code):

* :mod:`.frontend` — :func:`assign_chirps` (the receiver's front end: chirps
  assigned to beacons by their periodicity, ΔP per period, section 2) and
  :func:`clock_pseudo_ranges` (pseudo-ranges from a beacon-clock model, section 5);
* :mod:`.pf` — :class:`DopplerPf`, the 6-D particle filter of section 4.2 on the
  particle engine (:class:`uwbwb.filters.particle.ParticleFilter`, :meth:`DopplerPf.engine`),
  vectorised over particles and runs; :class:`PfRuns`, its runs as :class:`~uwbwb.types.Estimates` fields batched along
  a leading run axis;
* :mod:`.scaat` — :class:`ScaatMhEkf`, the SCAAT multi-hypothesis EKF of section 4.1 on
  :class:`~uwbwb.filters.ekf.Ekf`'s prediction and update (each hypothesis weighted by the
  update's innovation likelihood), with :class:`DopplerMeasurement` (the EKF's view of :class:`~uwbwb.models.doppler.DopplerModel`).

Both filters take the same :class:`~uwbwb.models.doppler.DopplerModel` (eq 1, noise) and
:class:`~uwbwb.models.motion.ReceiverMotion`, and give :class:`uwbwb.types.Estimates` per run.
"""

from __future__ import annotations

from .frontend import assign_chirps, clock_pseudo_ranges
from .pf import DopplerPf, PfRuns
from .scaat import DopplerMeasurement, ScaatMhEkf

__all__ = ["assign_chirps", "clock_pseudo_ranges", "DopplerMeasurement", "DopplerPf", "PfRuns", "ScaatMhEkf"]
