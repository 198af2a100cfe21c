"""UWB/INS fusion by error-state Kalman filters (paper 004): the paper's loose filter and a tight one.

Both run the strapdown mechanization of :mod:`uwbwb.models.ins` at the IMU rate and
correct it at the UWB epochs; every prediction and update goes through
:mod:`uwbwb.filters.kalman`. Results come back as :class:`FusionRun` (with
:meth:`FusionRun.to_estimates` giving the common :class:`~uwbwb.types.Estimates`).

**Loose — the paper's filter (eqs 5–7).** Error state ``[δP_E, δP_N, δV_E, δV_N]``
(``dim=2``; ``dim=3`` adds the vertical pair for a flying platform), constant-velocity
transition ``A`` with the UWB period ``T``, ``H = I`` and
``z = [P_ins − P_uwb; V_ins − V_uwb]``. ``P_uwb`` is a UWB position fix (TDoA least
squares after the eq-4 test); ``V_uwb`` is its backward difference over ``vel_window``
epochs, ``(P_k − P_{k−w}) / (t_k − t_{k−w})``. The INS attitude comes, as in the paper's
IMU, from the gyro with a complementary correction towards accelerometer levelling and,
where there is one, the magnetometer heading (time constant ``attitude_tau_s``); the
filter does not estimate attitude or sensor biases. The update is the Gaussian engine's
(:func:`~uwbwb.filters.gating.ungated_update` on a linear
:class:`~uwbwb.filters.ekf.Linearisation`), gated by an injected per-epoch policy
(:class:`~uwbwb.filters.gating.NoGate` or :class:`~uwbwb.filters.gating.ChiSquareEpoch`). Closed
loop: the estimated errors are subtracted from the INS position and velocity and the error
state is reset to zero.

**Tight.** Error state ``[δp, δv, δθ, δb_a, δb_g]`` (15; :mod:`uwbwb.models.ins`),
propagated with the IMU (``F = I + AΔt + ½(AΔt)²``, ``Q`` from the
:class:`~uwbwb.models.imu.ImuErrorModel`). Every TDoA (or range) of an epoch is its own
scalar update, with the Jacobian of ``h = ‖p + C l − a_j‖ − ‖p + C l − a_ref‖`` with
respect to position *and attitude* (lever arm ``l``): first the eq-4 test drops
implausible TDoAs, then each remaining TDoA must pass a χ²(1) innovation gate
(``gate_prob``) against the prior, then the survivors are applied one at a time
(decorrelated through the Cholesky factor of their reference-correlated covariance,
:func:`~uwbwb.filters.kalman.update_sequential`). So a single TDoA still corrects the
INS when too few stations are heard for a position fix. Optional pseudo-measurements:
a magnetometer heading and a known tag height (a ground robot). Closed loop
(``feedback=True``): after the epoch the error estimate is injected into the nominal
state, the error reset to zero and ``P ← G P Gᵀ``
(:func:`~uwbwb.models.ins.reset_jacobian`). With ``feedback=False`` the nominal INS
runs open loop and the error state carries the whole correction (output = nominal ⊕ δx).

Time: the IMU samples and the UWB epochs are merged into one time line; IMU values at
a UWB epoch are interpolated linearly between neighbouring samples, so each update happens at
its own time stamp. Across an IMU gap (longer than ``max_imu_gap_s``; :func:`gap_timeline`) no
filter interpolates: each coasts (velocity and attitude held, covariance grown by an assumed
motion, :func:`~uwbwb.models.ins.coast_transition` / :func:`~uwbwb.models.ins.coast`; the loose
filter grows its position/velocity block only), keeps updating with UWB, and lists the gaps in
``FusionRun.meta["imu_gaps_s"]``; :func:`dead_reckon` holds velocity and attitude the same way
and also marks the epochs after the first gap (``meta["imu_coasted"]``).

Modules: :mod:`.common` (constants, the time line and IMU gaps), :mod:`.updates` (TDoA and range
measurement models), :mod:`.result` (:class:`FusionRun`, :func:`dead_reckon`), :mod:`.tight`
(:class:`TightEskf` and its Python reference :meth:`TightEskf.run_reference`), :mod:`.kernels`
(the compiled loops and their pieces, each tested equal to its Python twin), :mod:`.loose`
(:class:`LooseFilter` and its Python reference :meth:`LooseFilter.run_reference`). Every public name is importable from ``uwbwb.filters.eskf``.
"""

from .common import (HEADING_KNOWN_RAD, LOST_BUILD_S, MAX_IMU_GAP_STEPS, SNAPSHOT_RMS_SIGMAS, gap_timeline, imu_gaps,
                     merge_timeline)
from .kernels import _fill_row, _reset_block, _reset_covariance, _skew_into, _tight_loop, _uwb_rows
from ...models.ins import _exp_left_nb
from .loose import LooseFilter
from .result import FusionRun, dead_reckon
from .tight import TightEskf
from ...models.imu import HeadingLog
from .updates import RangeUpdate, TdoaUpdate, _tag_jacobian

__all__ = ["FusionRun", "HeadingLog", "LooseFilter", "RangeUpdate", "TdoaUpdate", "TightEskf", "dead_reckon",
           "gap_timeline", "imu_gaps", "merge_timeline"]
