"""Notebook 03's real-data sections: the ``lias-planar-uwb`` dynamic run (2-D, calibrated and raw
ranges) and the ``iasl-uwb-imu`` drone scenarios (3-D), each a calibrate-then-test study.

Each function loads what it needs, says in a banner whether the data was found, and returns the
studies (empty when the data is absent: the section is skipped, never replaced by synthetic data).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Mapping, Sequence

import numpy as np

from ... import calibration, datasets, widgets
from ...datasets import iasl
from ...errors import DataNotFoundError
from ...scoreboard.protocol import split_in_time
from .study import Study, run_study, tag_runs

__all__ = ["Section", "iasl_section", "lias_section"]


@dataclass(frozen=True)
class Section:
    """A real-data section of notebook 03 (:func:`lias_section`, :func:`iasl_section`).

    Attributes
    ----------
    banner
        Whether the data was found (HTML, for ``display``).
    studies
        Variant → study: LIAS ``{"calibrated ranges": Study, "raw ranges": Study}``, IASL ``{"3-D": Study}``;
        empty when the data is absent.
    label
        The recording's label (``"lias-planar-uwb/<run>"``, the IASL test scenario's), or ``""``.
    mount, range_calibration
        LIAS: the tag heights and the per-pair range calibration, both fitted on the static poses (None when absent).
    cleaning_report
        LIAS: the loader's cleaning report of the dynamic run.
    """

    banner: Any
    studies: Mapping[str, Study] = field(default_factory=dict)
    label: str = ""
    mount: Any = None
    range_calibration: Any = None
    cleaning_report: str = ""


def lias_section(data_dir, recording: str, static_session: str, *, tags: Sequence[str] | None, rate_hz: float,
                 fast: bool, grids, ref: int, gate_prob: float | None, scheduler=None) -> Section:
    """Calibrate on the first half of the LIAS dynamic run ``recording`` and test on the second half.

    Two range variants: calibrated per anchor–tag pair (fitted on the static poses of
    ``static_session``) and as logged. The driving noise is calibrated over ``grids`` on the
    calibrated ranges and reused for the raw ones. The tag heights come from the static poses,
    never from the scored run. ``fast`` thins each static recording (every 20th epoch, keeping at
    least 100).
    """
    room = datasets.load_lias_room(data_dir, recording, static_session)
    if not room.real:
        return Section(widgets.data_banner(**room.banner_args()))
    rec, static = room.dynamic, list(room.static)
    if fast:   # every 20th epoch, keeping at least 100 per static recording (short files are used whole)
        static = [r.decimate(max(1, min(20, min(len(log) for log in r.ranges.values()) // 100))) for r in static]
    mount = calibration.tag_mount_height(static)
    range_cal = calibration.fit_range_calibration(static)
    studies = {}
    for variant, r in {"calibrated ranges": range_cal.apply_recording(rec), "raw ranges": rec}.items():
        parts = split_in_time(r.decimate(rate_hz=rate_hz))      # the protocol's split: the first half calibrates
        # each part keeps the run's label; its name without brackets ("fast 0–67 s") is the summary's key, as before
        cal_runs, test_runs = (tag_runs(replace(p, name=r.name), tags, dim=2, z_m=mount.per_tag_m,
                                        name=p.name.replace("[", "").replace("]", "")) for p in parts)
        g = grids if not studies else {m: [s] for m, s in studies["calibrated ranges"].best.items()}
        studies[variant] = run_study(cal_runs, test_runs, grids=g, ref=ref, gate_prob=gate_prob, scheduler=scheduler)
    return Section(widgets.data_banner(**room.banner_args()), studies, rec.label, mount, range_cal,
                       rec.cleaning_report())


def iasl_section(data_dir, cal_scenario: str, scenario: str, *, rate_hz: float, grids, ref: int,
                 gate_prob: float | None, scheduler=None) -> Section:
    """Calibrate the 3-D filters on IASL ``cal_scenario`` and test them on ``scenario`` (variant ``"3-D"``)."""
    absent = "not found in the data folders"
    if datasets.dataset_available("iasl-uwb-imu", data_dir):
        try:
            cal, test = iasl.load_scenario(cal_scenario, data_dir), iasl.load_scenario(scenario, data_dir)
        except DataNotFoundError as exc:
            absent = f"the dataset is here, but {exc}"
        else:
            z = test.anchors.pos_m[:, 2]
            banner = widgets.data_banner("iasl-uwb-imu", True, detail=f"calibrated on {cal_scenario}, tested on "
                                         f"{scenario}; {len(z)} anchors at heights {np.unique(z.round(2))} m")
            study = run_study(tag_runs(cal, dim=3, rate_hz=rate_hz), tag_runs(test, dim=3, rate_hz=rate_hz),
                              grids=grids, ref=ref, gate_prob=gate_prob, scheduler=scheduler)
            return Section(banner, {"3-D": study}, test.label)
    return Section(widgets.data_banner("iasl-uwb-imu", False, detail=absent))
