"""The real-range part of notebook 01: sensor sets emulated on ``lias-planar-uwb`` two-way ranges.

LIAS has no sensor sets, so :func:`emulate_fixes` makes them
(:func:`uwbwb.sim.setnoise.emulate_set_fixes` on every ``decimate``-th epoch; LIAS ranges come at ~100 Hz,
10 gives about the paper's fix rate): per epoch the
``set_size`` anchors with the strongest emulated received power (path loss plus
fading, the simulator's selection rule) form the set, and the fix is the 2-D
least-squares position from that set's ranges at the tag's mount height, which
comes from the static calibration poses (:func:`uwbwb.calibration.tag_mount_height`),
never from the test run's truth. :func:`real_study` calibrates the set-noise model
on the static poses and emulates the dynamic run's fixes.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from ... import validate
from ...calibration import (MountHeight, RangeCalibration, fit_range_calibration, fit_set_noise_from_fixes,
                           tag_mount_height)
from ...datasets.standin import RoomData, load_lias_room
from ...models.setnoise import SetNoiseModel
from ...sim import rig
from ...sim import setnoise as sim
from ...types import Recording, SetFixLog


def real_inputs(data_dir=None, recording: str = "fast", static_session: str = "8.14", *, seed: int = 0,
                fast: bool = False) -> RoomData:
    """A LIAS dynamic run and the static poses of its room, or the synthetic rig if absent.

    With ``fast`` only the first yaw of every static site is kept (5 poses instead of 30).
    """
    stand_in = rig.RigConfig(duration_s=60.0 if fast else 120.0)
    room = load_lias_room(data_dir, recording, static_session, stand_in=stand_in,
                          static_duration_s=10.0 if fast else 20.0, rng=np.random.default_rng(seed))
    if fast and room.real:
        first = {}
        for rec in room.static:
            first.setdefault(rec.meta["site"], rec)
        room = replace(room, static=tuple(first.values()),
                       note=room.note + f" (FAST: first yaw of each of {len(first)} sites)")
    return room


def emulate_fixes(rec: Recording, tag: str, emulation: sim.SetEmulation = sim.SetEmulation(), *, tag_height_m: float,
                  rng: np.random.Generator, decimate: int = 10, calibration: RangeCalibration | None = None,
                  name: str | None = None) -> tuple[SetFixLog, dict]:
    """Position fixes of one tag from sensor sets emulated on every ``decimate``-th epoch (:meth:`Recording.decimate`).

    Parameters
    ----------
    rec
        A recording with ranges and truth for ``tag`` (truth scores the fixes only).
    tag_height_m
        The tag's mount height, metres (from calibration material, e.g.
        :func:`uwbwb.calibration.tag_mount_height` of static poses).
    calibration
        Optional per-pair range calibration applied to the ranges first.

    Returns
    -------
    fixes
        :class:`SetFixLog` with truth, named ``name`` (default ``"<recording>/<tag>"``).
    report
        Counts: ``epochs``, ``kept_after_decimation``, ``no_truth`` (outside the
        motion capture), ``too_few_ranges`` (fewer than ``set_size``), ``fix_failed``,
        ``fixes``, and ``coverage`` = fixes ÷ decimated epochs with truth (every
        estimator is scored on the fixes only, so this is their common coverage).
    """
    log = rec.decimate(validate.integer("decimate", decimate, minimum=1)).ranges_of(tag, calibration)
    truth_xyz = rec.truth[tag].interp(log.t_s)
    has_truth = np.all(np.isfinite(truth_xyz), axis=1)
    em = sim.emulate_set_fixes(log.select(has_truth), rec.anchors.pos_m, tag_height_m, emulation, rng=rng,
                               truth_m=truth_xyz[has_truth][:, :2], name=name or f"{rec.name}/{tag}")
    fixes = em.fixes
    scored = int(has_truth.sum())
    report = {"epochs": len(rec.ranges[tag]), "kept_after_decimation": len(log),
              "no_truth": int((~has_truth).sum()), "too_few_ranges": em.too_few_ranges,
              "fix_failed": em.fix_failed, "fixes": len(fixes),
              "coverage": len(fixes) / scored if scored else float("nan")}
    return fixes, report


@dataclass(frozen=True)
class RealStudy:
    """The set-noise model calibrated on static poses and the dynamic run's fixes per tag."""

    range_calibration: RangeCalibration | None
    tag_height: MountHeight
    calibration: tuple[SetFixLog, ...]
    model: SetNoiseModel
    pooled: SetNoiseModel
    tests: tuple[SetFixLog, ...]
    reports: pd.DataFrame = field(repr=False)

    def coverage(self) -> pd.DataFrame:
        """Per role (calibration / test): fixes, decimated epochs with truth, coverage."""
        g = self.reports.groupby("role")[["kept_after_decimation", "no_truth", "fixes"]].sum()
        g["scorable"] = g["kept_after_decimation"] - g["no_truth"]
        g["coverage"] = g["fixes"] / g["scorable"]
        return g[["scorable", "fixes", "coverage"]]


def real_study(inputs: RoomData, emulation: sim.SetEmulation = sim.SetEmulation(), *, decimate: int = 10,
               range_calibration: bool = True, tags=None, rng: np.random.Generator) -> RealStudy:
    """Calibrate the set-noise model on the static poses and emulate the dynamic run's fixes.

    Every (static pose, tag) is one calibration location. With ``range_calibration``
    the per-pair range bias/scale fitted on the *same* static poses
    (:func:`uwbwb.calibration.fit_range_calibration`, on the epochs the emulation
    keeps) is applied to all ranges first. The tags' mount height comes from the
    static poses (:func:`uwbwb.calibration.tag_mount_height`).
    """
    cal = None
    if range_calibration:
        cal = fit_range_calibration([rec.decimate(decimate) for rec in inputs.static])
    tags = tuple(inputs.dynamic.tags if tags is None else tags)
    height = tag_mount_height(inputs.static, tags=tags)
    logs, rows = [], []
    for rec in inputs.static:
        for tag in tags:
            fixes, rep = emulate_fixes(rec, tag, emulation, tag_height_m=height.per_tag_m[tag], rng=rng,
                                       decimate=decimate, calibration=cal, name=f"{rec.name}/{tag}")
            logs.append(fixes)
            rows.append({"recording": rec.name, "tag": tag, "role": "calibration", **rep})
    model = fit_set_noise_from_fixes(logs)
    pooled = fit_set_noise_from_fixes(logs, sigma_rule="pooled")
    tests = []
    for tag in tags:
        fixes, rep = emulate_fixes(inputs.dynamic, tag, emulation, tag_height_m=height.per_tag_m[tag], rng=rng,
                                   decimate=decimate, calibration=cal)
        tests.append(fixes)
        rows.append({"recording": inputs.dynamic.name, "tag": tag, "role": "test", **rep})
    return RealStudy(cal, height, tuple(logs), model, pooled, tuple(tests), pd.DataFrame(rows))


def modelled_share(log: SetFixLog, model: SetNoiseModel) -> float:
    """Fraction of fixes whose set has its own model (the rest use the facility-wide default)."""
    return float(model.lookup(log.set_id)[2].mean())
