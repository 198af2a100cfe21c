"""Notebook 01: sensor-set switching noise and the set-noise particle filter (paper 000).

:mod:`.study` is the synthetic re-creation (facility, calibration, Table I, the
Fig. 9 sweep), :mod:`.diagnostics` its Fig. 8 run, the PF → KF gap and the
noise models' residuals, :mod:`.real`
the sets emulated on ``lias-planar-uwb`` ranges, :mod:`.figures` the figure
builders, :mod:`.headlines` the summary rows (synthetic and real, each with its kind), the checks and the verdict
table of the comparison with the paper, and
:mod:`.panels` the widget's back end. Everything the notebook uses is importable from here.
"""

from . import exercises, headlines, panels
from .figures import (plot_facility, plot_fixes, plot_pf_kf_gap, plot_set_ellipses, plot_set_frequency,
                      plot_sweep, plot_trace)
from .real import RealStudy, emulate_fixes, modelled_share, real_inputs, real_study
from .diagnostics import FACILITY_WIDE, PAPER_SIGMA_RULE, POOLED_SIGMA_RULE, pf_kf_gap, residual_table, trace
from .headlines import headline_rows
from .study import (BAND_MPS, BASE_KF, BASE_PF, FILTERS, OFF_TRACK_XY_M, PAPER, RAW, SET_KF,
                    SET_KF_POOLED, SET_PF, SIGMA_D_GRID_MPS, SweepConfig, SyntheticStudy, band_summary,
                    calibration_proximity, mean_over_recordings, raw_error_m, set_shares, sweep, synthetic_study,
                    table1)

__all__ = [
    "BAND_MPS", "BASE_KF", "BASE_PF", "FACILITY_WIDE", "FILTERS", "OFF_TRACK_XY_M", "PAPER",
    "PAPER_SIGMA_RULE", "POOLED_SIGMA_RULE", "RAW", "SET_KF", "SET_KF_POOLED", "SET_PF",
    "SIGMA_D_GRID_MPS", "RealStudy", "SweepConfig", "SyntheticStudy", "band_summary",
    "calibration_proximity", "emulate_fixes", "exercises", "headline_rows", "headlines", "mean_over_recordings",
    "modelled_share", "panels", "pf_kf_gap", "plot_facility", "plot_fixes", "plot_pf_kf_gap",
    "plot_set_ellipses", "plot_set_frequency", "plot_sweep", "plot_trace", "raw_error_m", "real_inputs", "real_study",
    "residual_table", "set_shares", "sweep", "synthetic_study", "table1", "trace",
]
