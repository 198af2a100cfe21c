"""Containers shared by loaders, simulators, estimators and notebooks.

All containers are frozen dataclasses holding read-only numpy arrays in SI
units, time-major: ``t_s`` has shape ``(T,)``, per-epoch quantities ``(T, ...)``.
They validate shapes and units in ``__post_init__``; change them with
:func:`dataclasses.replace`. Every container has a tidy ``to_frame`` and a
matching ``from_frame`` so that round trips through pandas are exact.

One module per family, every name importable from ``uwbwb.types``:
:mod:`.containers` (``Anchors``, ``RangeLog``, ``Trajectory``, ``ImuLog``, ``CleaningStep``),
:mod:`.recording` (``Recording``), :mod:`.tdoa` (``TdoaLog``, ``pseudo_tdoa``),
:mod:`.sets` (sensor-set fixes of paper 000), :mod:`.samples` (``RangeSamples``, ``TagRun``),
:mod:`.estimates` (``Estimates``, ``EstimateStatus``: what every estimator returns; ``EstimatesBatch``: the
same fields batched over the runs of a sweep),
:mod:`.chirps` (``ChirpLog``, ``ChirpFlag``); the array-record base (``ArrayRecord``: ``select``, ``between``,
``shifted``, ``to_frame`` written once, with the one time-window rule) and the truth-gap constant
``MAX_TRUTH_GAP_S`` in :mod:`._base`.
"""

from ._base import _check_time, _frozen_array, _natural_key  # noqa: F401 (used by the loaders)
from ._base import MAX_TRUTH_GAP_S, ArrayRecord
from .containers import CleaningStep, Anchors, RangeLog, Trajectory, ImuLog
from .recording import Recording
from .tdoa import pseudo_tdoa, TdoaLog
from .sets import set_id_from_mask, set_members, set_mask, set_label, parse_set_label, SetFixLog
from .samples import RangeSamples, TagRun
from .estimates import EstimateStatus, Estimates, EstimatesBatch
from .chirps import ChirpFlag, ChirpLog

__all__ = ["Anchors", "ArrayRecord", "MAX_TRUTH_GAP_S", "ChirpFlag", "ChirpLog", "CleaningStep", "Estimates", "EstimatesBatch", "EstimateStatus", "ImuLog",
           "parse_set_label", "pseudo_tdoa", "RangeLog", "RangeSamples", "Recording", "set_id_from_mask",
           "set_label", "set_mask", "set_members", "SetFixLog", "TagRun", "TdoaLog", "Trajectory"]

# The classes keep ``uwbwb.types`` as their home module, as before the split: pickles, reprs and
# documentation references name ``uwbwb.types.<Class>``, which stays importable.
for _cls in (Anchors, ArrayRecord, ChirpFlag, ChirpLog, CleaningStep, EstimateStatus, Estimates, EstimatesBatch, ImuLog, RangeLog, RangeSamples,
             Recording, SetFixLog, TagRun, TdoaLog, Trajectory):
    _cls.__module__ = __name__
del _cls
