"""A room's real recordings, or a synthetic stand-in, and the reason for the choice.

Notebooks that work on the ``lias-planar-uwb`` room (a dynamic run to test on and
the static poses of the same room to calibrate with) load it through
:func:`load_lias_room`. When the *dataset* is absent, the synthetic rig of
:mod:`uwbwb.sim.rig` (same structure: eight anchors, three tags on a trolley, per-pair
range biases) stands in if the caller asked for one, or nothing does, and the result
says why; ``uw.widgets.data_banner(**room.banner_args())`` shows it. When the dataset is here but holds no
recording or session of the requested name, that is an error listing the names it does
hold (:class:`~uwbwb.errors.DataNotFoundError`): a misspelt name never turns into
synthetic data.

The data layer sits above the simulators (:mod:`uwbwb.sim`), so the stand-in is built
here; the banner is drawn by :mod:`uwbwb.widgets`, a layer above, from :meth:`RoomData.banner_args`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import DataNotFoundError
from ..sim import rig
from ..types import Recording
from .discovery import dataset_available, find_dataset

__all__ = ["LIAS", "RoomData", "load_lias_room"]

#: Dataset name of the planar trolley recordings.
LIAS = "lias-planar-uwb"


@dataclass(frozen=True)
class RoomData:
    """A dynamic run and the static calibration poses of its room, and where they came from.

    Attributes
    ----------
    dataset
        The dataset that was asked for.
    dynamic
        The moving recording to test on; None when neither the data nor a stand-in is there.
    static
        Static recordings of the same room (calibration material).
    synthetic
        True when the synthetic rig stands in for the real data.
    reason
        Why the real data is not used (empty when it is).
    note
        One sentence saying what data this is.
    """

    dataset: str
    dynamic: Recording | None
    static: tuple[Recording, ...]
    synthetic: bool
    reason: str
    note: str

    @property
    def real(self) -> bool:
        """Whether real recordings were loaded."""
        return self.dynamic is not None and not self.synthetic

    @property
    def data_label(self) -> str:
        """The ``data`` field of summary rows: ``synthetic`` or ``dataset/recording``."""
        if self.dynamic is None:
            raise ValueError(f"{self.dataset}: no data was loaded ({self.reason})")
        return "synthetic" if self.synthetic else self.dynamic.label

    def banner_args(self, instead: str | None = None) -> dict:
        """Keyword arguments of :func:`uwbwb.widgets.data_banner` for this data (``instead``
        overrides the default wording): ``uw.widgets.data_banner(**room.banner_args())``."""
        if self.real:
            return {"dataset": self.dataset, "found": True, "detail": self.note}
        if instead is None:
            instead = ("every number below comes from the synthetic stand-in, not from real data: " + self.note
                       if self.synthetic else "this section is skipped")
        return {"dataset": self.dataset, "found": False, "detail": self.reason, "instead": instead}


def load_lias_room(data_dir=None, recording: str = "fast", static_session: str = "8.14", *,
                   static_yaws: Sequence[int] | None = None, stand_in=None, static_duration_s: float = 20.0,
                   rng: np.random.Generator | None = None) -> RoomData:
    """Load a ``lias-planar-uwb`` dynamic run and its room's static poses, or stand in for them.

    Parameters
    ----------
    data_dir
        Folder holding dataset folders (None: the package's search order).
    recording
        Dynamic run, as in ``UWB_dynamic_exp_<recording>.csv``.
    static_session
        Static session folder of the same room (``"8.14"``, ``"8.20"``).
    static_yaws
        Load only these nominal yaws of every site (default: all).
    stand_in
        A :class:`uwbwb.sim.rig.RigConfig`: simulate that rig when the dataset is
        absent. None: return no data (``dynamic`` None) instead.
    static_duration_s
        Length of each simulated static pose, seconds.
    rng
        Needed when a stand-in is simulated: the dynamic run is drawn first, then
        the static poses with the same range model.

    Returns
    -------
    RoomData
        The recordings, whether they are synthetic, and why.

    Raises
    ------
    DataNotFoundError
        The dataset is here but has no dynamic run ``recording`` or no static session
        ``static_session`` (the message lists the names it has).
    """
    if dataset_available(LIAS, data_dir):
        from . import lias

        try:
            dynamic = lias.load_dynamic(recording, data_dir)
            yaws = (None,) if static_yaws is None else tuple(static_yaws)
            static = tuple(r for yaw in yaws for r in lias.load_static(static_session, data_dir, yaw_deg=yaw))
        except DataNotFoundError as exc:
            table = lias.list_recordings(data_dir)
            runs = list(table.loc[table["kind"] == "dynamic", "name"])
            sessions = list(dict.fromkeys(table.loc[table["kind"] == "static", "session"]))
            raise DataNotFoundError(f"{LIAS} is in {find_dataset(LIAS, data_dir)} but this failed: {exc}. "
                                    f"Dynamic runs there: {runs}; static sessions: {sessions}. "
                                    f"(A stand-in replaces only a dataset that is absent, never a wrong name.)"
                                    ) from exc
        return RoomData(LIAS, dynamic, static, False, "",
                        f"dynamic run {recording!r}, {len(static)} static poses of session {static_session}")
    reason = f"{LIAS} was not found in the data folders"
    if stand_in is None:
        return RoomData(LIAS, None, (), False, reason, "nothing loaded")
    if rng is None:
        raise ValueError("load_lias_room: a stand-in needs rng")
    dynamic, truth = rig.simulate_dynamic(stand_in, rng=rng)
    static, _ = rig.simulate_static(stand_in, duration_s=static_duration_s, rng=rng, range_model=truth.range_model)
    return RoomData(LIAS, dynamic, tuple(static), True, reason,
                    f"synthetic rig (uwbwb.sim.rig: {len(dynamic.anchors)} anchors, {len(dynamic.tags)} tags, "
                    f"per-pair range biases), {len(static)} static poses")
