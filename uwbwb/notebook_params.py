"""What each notebook parameter accepts: type, range, what None means, what FAST does to it.

``python -m uwbwb reproduce -p NAME VALUE`` (and :func:`uwbwb.reproduce.reproduce`)
checks every value against the notebook's :class:`Spec` before any notebook runs,
and the value reaches the notebook with the type the spec gives it (a tuple stays
a tuple). The table :data:`SPECS` is keyed by notebook stem; parameters every
notebook shares are in :data:`COMMON`. A test reads every notebook's
``parameters`` cell and fails for a parameter without a spec, so a parameter
added to a notebook is added here too::

    "02_pruning_nls": {
        "TOURS": seq(integer(choices=(1, 2, 3)), fast="runs tour 2 only"),
        ...
    }

Notebooks not in the table (your own) get a spec inferred from each default
(:func:`infer`): the default's type, any value of it.

FAST mode: ``fast`` says that the notebook replaces an explicit value under
``FAST=True`` (e.g. its own short tour list); ``fast_cap`` that it caps the value
at that number. An explicit value FAST would replace or lower is refused under
FAST (``--quick``), never silently dropped (:func:`conflict`).
"""

from __future__ import annotations

import ast
import math
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .parallel import check_scheduler_address

__all__ = ["COMMON", "INT_MAX", "SPECS", "Spec", "conflict", "flag", "infer", "integer", "real", "seq",
           "specs_for", "text"]

#: Largest integer a count may take (the int64 range NumPy sizes and seeds live in).
INT_MAX = 2**63 - 1


def _fmt(x) -> str:
    if isinstance(x, float) and x.is_integer() and abs(x) >= 1e6:
        return f"{x:.0e}"
    if isinstance(x, int) and x == INT_MAX:
        return "2**63 - 1"
    return f"{x:g}" if isinstance(x, float) else repr(x)


@dataclass(frozen=True)
class Spec:
    """What one notebook parameter accepts.

    Attributes
    ----------
    kind
        ``"bool"``, ``"int"``, ``"float"``, ``"str"``, ``"tuple"`` or ``"any"`` (any Python
        literal, or the text as typed: only for parameters of notebooks without a table).
    lo, hi, lo_open, hi_open
        Range of an int or float (closed unless ``*_open``); None: unbounded.
    choices
        The only values allowed (int or str), or None.
    none
        What ``None`` means for this parameter (then ``None`` is accepted); None: not accepted.
    item
        Spec of every element of a tuple.
    min_len, increasing
        Tuples: fewest elements; elements strictly increasing.
    allow_empty
        Text: whether ``""`` is accepted.
    fast, fast_cap
        What the notebook does to an explicit value under ``FAST=True``: replaces it
        (``fast`` says with what), or caps it at ``fast_cap`` (a larger value, or None,
        is lowered). See :func:`conflict`.
    check
        Further check ``check(value, name)`` raising ``ValueError`` (e.g. an address format).
    """

    kind: str
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple | None = None
    none: str | None = None
    item: "Spec | None" = None
    min_len: int = 1
    increasing: bool = False
    allow_empty: bool = False
    fast: str | None = None
    fast_cap: float | None = None
    check: Callable[[Any, str], None] | None = field(default=None, compare=False)

    # ------------------------------------------------------------------ description

    def expected(self) -> str:
        """What the parameter accepts, in words (used in error messages and the README)."""
        if self.kind == "bool":
            what = "True or False"
        elif self.kind == "any":
            what = "a Python literal or text"
        elif self.kind == "tuple":
            item = self.item.expected() if self.item is not None else "any value"
            what = f"a tuple of {'at least ' + str(self.min_len) + ' ' if self.min_len > 1 else ''}" \
                   f"{'strictly increasing ' if self.increasing else ''}" \
                   f"{'distinct ' if self.item is not None and self.item.kind == 'str' else ''}values, each {item}"
        elif self.choices is not None:
            what = "one of " + ", ".join(map(repr, self.choices))
        elif self.kind in ("int", "float"):
            what = "an integer" if self.kind == "int" else "a number"
            full = self.kind == "int" and self.lo in (None, -INT_MAX - 1) and self.hi in (None, INT_MAX)
            lo = None if self.lo is None or full else f"{'>' if self.lo_open else '≥'} {_fmt(self.lo)}"
            hi = None if self.hi is None or full else f"{'<' if self.hi_open else '≤'} {_fmt(self.hi)}"
            if lo and hi:
                what += f" {lo} and {hi}"
            elif lo or hi:
                what += f" {lo or hi}"
        else:
            what = "text" if self.allow_empty else "non-empty text"
        if self.none is not None:
            what += f", or None ({self.none})"
        return what

    # ------------------------------------------------------------------ checking

    def validate(self, value: Any, name: str = "value") -> Any:
        """``value`` in this parameter's type (an int for a float parameter becomes a float, a list
        for a tuple parameter a tuple, an integral float for an int parameter an int).

        Raises
        ------
        ValueError
            Naming the parameter, the value and what was expected.
        """
        out = self._convert(value)
        if out is _BAD:
            raise ValueError(f"{name}={_short(value)}: expected {self.expected()}")
        if self.check is not None and out is not None:
            self.check(out, name)
        return out

    def parse(self, text: str, name: str = "value") -> Any:
        """A value typed on the command line (``-p NAME TEXT``), checked by :meth:`validate`.

        Text parameters take the text exactly as typed (``8.20`` stays ``"8.20"``), except
        ``None`` where None is accepted; booleans take ``True``/``False`` (also lower case);
        everything else is read as a Python literal (``(2.5, 4, 40)``, ``1e9``, ``None``).

        Raises
        ------
        ValueError
            ``-p NAME TEXT: expected ...``.
        """
        stripped = text.strip()
        if self.none is not None and stripped == "None":
            return None
        value = text               # text that is no literal stays text: only "any" accepts it
        if self.kind == "bool":
            value = {"True": True, "true": True, "False": False, "false": False}.get(stripped, text)
        elif self.kind != "str":
            try:
                value = ast.literal_eval(stripped)
            except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
                pass
        try:
            return self.validate(value, name)
        except ValueError as exc:
            msg = str(exc).removeprefix(f"{name}={_short(value)}: ")
            msg = msg.split(": ", 1)[1] if msg.startswith(f"{name}=") else msg
            raise ValueError(f"-p {name} {_short(text, quote=False)}: {msg}") from None

    def _convert(self, value: Any) -> Any:
        # NumPy scalars and paths, as a Python caller passes them, are the plain values they stand for
        if isinstance(value, np.bool_):
            value = bool(value)
        elif isinstance(value, np.integer):
            value = int(value)
        elif isinstance(value, np.floating):
            value = float(value)
        elif isinstance(value, os.PathLike) and self.kind == "str":
            value = os.fspath(value)
        if value is None:
            return None if self.none is not None or self.kind == "any" else _BAD
        if self.kind == "any":
            return value
        if self.kind == "bool":
            return value if isinstance(value, bool) else _BAD
        if self.kind == "str":
            if not isinstance(value, str) or (not value and not self.allow_empty):
                return _BAD
            return value if self.choices is None or value in self.choices else _BAD
        if self.kind == "int":
            if isinstance(value, float) and math.isfinite(value) and value.is_integer():
                value = int(value)                                  # 1e9 draws
            if not isinstance(value, int) or isinstance(value, bool):
                return _BAD
            if self.choices is not None:
                return value if value in self.choices else _BAD
            return value if self._in_range(value) else _BAD
        if self.kind == "float":
            if not isinstance(value, (int, float)) or isinstance(value, bool):
                return _BAD
            try:
                value = float(value)
            except OverflowError:
                return _BAD
            return value if math.isfinite(value) and self._in_range(value) else _BAD
        if self.kind == "tuple":
            if not isinstance(value, (tuple, list)) or len(value) < self.min_len:
                return _BAD
            items = tuple(value) if self.item is None else tuple(self.item._convert(v) for v in value)
            if any(v is _BAD for v in items):
                return _BAD
            if self.item is not None and self.item.kind == "str" and len(set(items)) < len(items):
                return _BAD                                         # a tag named twice would run twice
            if self.increasing and any(not a < b for a, b in zip(items, items[1:])):
                return _BAD
            return items
        raise ValueError(f"unknown parameter kind {self.kind!r}")

    def _in_range(self, x) -> bool:
        if self.lo is not None and (x < self.lo or (self.lo_open and x == self.lo)):
            return False
        if self.hi is not None and (x > self.hi or (self.hi_open and x == self.hi)):
            return False
        return True


_BAD = object()


def _short(value, quote: bool = True) -> str:
    text = repr(value) if quote else str(value)
    return text if len(text) <= 60 else text[:40] + "…" + text[-10:] + f" ({len(text)} characters)"


# ---------------------------------------------------------------------- constructors

def flag(**kw) -> Spec:
    """True or False."""
    return Spec("bool", **kw)


def integer(lo: int | None = None, hi: int | None = INT_MAX, **kw) -> Spec:
    """An integer in ``[lo, hi]`` (or one of ``choices=``)."""
    return Spec("int", lo=lo, hi=hi, **kw)


def real(lo: float | None = None, hi: float | None = None, **kw) -> Spec:
    """A finite number in ``[lo, hi]`` (``lo_open``/``hi_open`` for open ends); an int is accepted."""
    return Spec("float", lo=lo, hi=hi, **kw)


def text(**kw) -> Spec:
    """Text (non-empty unless ``allow_empty=True``; one of ``choices=`` when given)."""
    return Spec("str", **kw)


def seq(item: Spec, **kw) -> Spec:
    """A tuple whose elements each satisfy ``item`` (a list is accepted and becomes a tuple)."""
    return Spec("tuple", item=item, **kw)


def infer(default: Any) -> Spec:
    """The spec of a parameter of a notebook without a table entry: its default's type, any value."""
    if default is None:
        return Spec("any")
    if isinstance(default, bool):
        return flag()
    if isinstance(default, int):
        return integer(lo=-INT_MAX - 1)
    if isinstance(default, float):
        return real()
    if isinstance(default, str):
        return text(allow_empty=True)
    if isinstance(default, (tuple, list)):
        kinds = {type(d) for d in default}
        item = infer(default[0]) if len(kinds) == 1 and default else None
        return seq(item, min_len=0) if item is not None else Spec("tuple", min_len=0)
    return Spec("any")


# ---------------------------------------------------------------------- the table

def _scheduler_address(value: str, name: str) -> None:
    """A ``DASK_SCHEDULER`` value: ``"local"`` or a well-formed scheduler address."""
    if value.strip() == "local":
        return
    if value.strip().startswith("inproc://"):     # the notebooks run in kernels of their own: they cannot reach it
        raise ValueError(f"{name}={value!r}: an inproc:// address lives inside one Python process and cannot be "
                         "reached from the notebooks' kernels; expected 'local' or an address such as "
                         "tcp://10.0.0.5:8786")
    try:
        check_scheduler_address(value)
    except ImportError as exc:
        raise ValueError(f"{name}={value!r} needs dask.distributed: {exc}") from None
    except ConnectionError as exc:
        raise ValueError(str(exc)) from None


def _existing_folder(value: str, name: str) -> None:
    """A ``DATA_DIR`` value: a folder that exists (a missing one would silently leave every notebook on its
    synthetic stand-in)."""
    path = Path(value).expanduser()
    if not path.is_dir():
        what = "is a file, not a folder" if path.exists() else "does not exist"
        raise ValueError(f"{name}={value!r}: {what}; expected the folder that holds the dataset folders "
                         "(e.g. ../shared/datasets), or None for the usual search")


#: The paper's σ_d band in cm/s (notebook 01): section 7, the verdict table and the summary average over it
#: (``uwbwb.experiments.setnoise.BAND_MPS`` in m/s; a test holds the two equal).
SIGMA_D_BAND_CMPS = (30.0, 50.0)


def _reaches_the_band(value: tuple, name: str) -> None:
    """A ``SIGMA_D_CMPS`` value: at least one σ_d in the paper's band, which notebook 01 averages over."""
    lo, hi = SIGMA_D_BAND_CMPS
    if not any(lo <= v <= hi for v in value):
        raise ValueError(f"{name}={value!r}: no value in the paper's band {lo:g}–{hi:g} cm/s, which notebook 01's "
                         f"band tables, verdicts and summary average over; add one, e.g. {value + (40.0,)!r}")


#: Parameters every notebook declares.
COMMON: dict[str, Spec] = {
    "FAST": flag(),
    "CLASS": flag(),     # a lecturer's run: FAST sizes or smaller, short output (``make class``)
    "SEED": integer(lo=0),
    "DATA_DIR": text(none="the usual search: $UWBWB_DATA, data/external, ../shared/datasets", check=_existing_folder),
    "SUMMARY_PATH": text(none="publish no summary"),
    "DASK_SCHEDULER": text(none="sweeps run in this process", check=_scheduler_address),
}

_RECORDING = text()          # a recording or folder name of the dataset; the loader says which exist

#: Per notebook stem: every parameter of its ``parameters`` cell beyond :data:`COMMON`.
SPECS: dict[str, dict[str, Spec]] = {
    "00_quickstart": {
        "RECORDING": _RECORDING,
        "STATIC_SESSION": _RECORDING,
    },
    "01_set_noise_pf": {
        "RECORDING": _RECORDING,
        "STATIC_SESSION": _RECORDING,
        "N_TRIALS": integer(lo=1, fast="runs its own CI-sized sweep (SweepConfig.fast())"),
        "N_PARTICLES": integer(lo=1, fast="runs its own CI-sized sweep (SweepConfig.fast())"),
        "SIGMA_D_CMPS": seq(real(lo=0, lo_open=True), increasing=True, check=_reaches_the_band,
                            fast="runs its own CI-sized sweep (SweepConfig.fast())"),
        "REAL_N_TRIALS": integer(lo=1, fast="runs 2 trials per σ_d on the real run"),
        "N_THREADS": integer(lo=1, hi=1024),
        "RANGE_CALIBRATION": flag(),
        "SET_SIZE": integer(lo=3, hi=64),
        "FADING_DB": real(lo=0, hi=100),
    },
    "02_pruning_nls": {
        "STATIC_SESSION": _RECORDING,
        "RECORDING": _RECORDING,
        "TOURS": seq(integer(choices=(1, 2, 3)), fast="runs tour 2 only"),
        "PACES": seq(text(choices=("slow", "fast")), fast="runs the fast pace only"),
        "NODES": seq(text(choices=("L", "H")), fast="runs node H only"),
        "RESIDUAL_RETENTION": real(lo=0, hi=1, lo_open=True),
        "RM_RETENTION": real(lo=0, hi=1, lo_open=True),
        "DIM": integer(choices=(2, 3)),
        "STATIC_STRIDE": integer(lo=1, fast="uses every 100th static epoch"),
        "DYNAMIC_STRIDE": integer(lo=1, fast="uses every 20th dynamic epoch"),
        "LIAS_TAGS": seq(text(), fast="uses tag t0 only"),
        "HANYANG_CASE": text(none="the first NLOS case of hanyang-outdoor-uwb"),
    },
    "03_ekf_motion_models": {
        "RECORDING": _RECORDING,
        "STATIC_SESSION": _RECORDING,
        "LIAS_TAGS": seq(text(), none="every tag of the run"),
        "IASL_CAL_SCENARIO": _RECORDING,
        "IASL_SCENARIO": _RECORDING,
        "HANYANG_CASE": text(none="the first LOS case of hanyang-outdoor-uwb"),
        "SIM_DURATION_S": real(lo=0, lo_open=True, hi=86400.0, fast_cap=60.0),
        "RATE_HZ": real(lo=0, lo_open=True, hi=1000.0),
        "GRID_POINTS": integer(lo=2, hi=1000, fast_cap=5),
        "REF_ANCHOR": integer(lo=0, hi=1023),
        "GATE_PROB": real(lo=0, hi=1, lo_open=True, hi_open=True, none="no gate"),
    },
    "04_doppler_beacons": {
        "N_BRUTE": integer(lo=1, none="1e9 draws (full), 2e7 (FAST)"),
        "N_POSITIONS": integer(lo=1, none="2e6 positions (full), 1e5 (FAST)"),
        "PF_RUNS": integer(lo=1, none="200 runs on the first recording (full), 8 (FAST)"),
        "N_PARTICLES": integer(lo=1, none="1000 particles (full), 800 (FAST)"),
        "N_RECORDINGS": integer(lo=1, none="10 recordings (full), 2 (FAST)"),
        "TEMPERATURE_C": real(lo=-50.0, hi=60.0),
        "SIGMA_RANGE_M": real(lo=0, lo_open=True, hi=10.0),
        "WORKERS": integer(lo=1, hi=1024),
    },
    "05_uwb_ins_fusion": {
        "IASL_CAL_SCENARIO": _RECORDING,
        "IASL_SCENARIO": _RECORDING,
        "GRADE": text(choices=("consumer", "industrial", "tactical")),
        "STATIC_S": real(lo=0, lo_open=True, hi=86400.0, fast_cap=20.0),
        "OUTLIER_RATE": real(lo=0, hi=1, hi_open=True),
        # the outage must end, with the recovery scored after it, inside the broken-line run
        # (experiments.uwb_ins.ablation.check_outage; a test keeps the bound equal to it)
        "OUTAGE_S": real(lo=0, lo_open=True, hi=18.6),
        "NLOS_BIAS_M": real(lo=0, hi=100.0),
        "OUTLIER_C_M": real(lo=0, lo_open=True, hi=100.0),
        "GATE_PROB": real(lo=0, hi=1, lo_open=True, hi_open=True),
        "LOOSE_WINDOW": integer(lo=1, hi=10_000),
        "RATE_HZ": real(lo=0, lo_open=True, hi=1000.0, fast_cap=5.0),
        "SEEDS": integer(lo=2, hi=100_000, fast="scores the ablation on 2 seeds (AblationConfig.fast)"),
    },
    "06_scoreboard": {
        "LIAS_RECORDING": _RECORDING,
        "IASL_CAL_SCENARIO": _RECORDING,
        "IASL_SCENARIO": _RECORDING,
        "RATE_HZ": real(lo=0, lo_open=True, hi=1000.0, fast_cap=5.0),
        "MC_RUNS": integer(lo=1, hi=1_000_000, fast_cap=15),
        "HANYANG_CASES": seq(text(), none="every hanyang-outdoor-uwb dynamic case present (FAST: the first)"),
    },
}


def specs_for(stem: str, declared: Mapping[str, Any]) -> dict[str, Spec]:
    """The spec of every parameter a notebook declares (``declared``: name → default).

    From :data:`SPECS` (and :data:`COMMON`) for a notebook of the table; inferred from the
    default (:func:`infer`) for a notebook outside it, and for a parameter the table lacks
    (a test keeps the table complete for the project's notebooks).
    """
    table = SPECS.get(stem)
    if table is None:
        return {name: infer(default) for name, default in declared.items()}
    known = COMMON | table
    return {name: known[name] if name in known else infer(default) for name, default in declared.items()}


def conflict(mode: str, stem: str, name: str, value: Any, spec: Spec) -> str | None:
    """Why an explicit ``name=value`` cannot hold when notebook ``stem`` runs with ``mode=True``, ``mode`` being
    ``"FAST"`` or ``"CLASS"`` (None if it can).

    Class mode runs at FAST sizes or smaller ones of its own (e.g. shorter walks, a coarser grid), so every
    parameter that FAST replaces or caps is set by the notebook there: an explicit value is refused.
    """
    if mode == "CLASS" and (spec.fast is not None or spec.fast_cap is not None):
        return (f"{stem}: {name}={value!r} would not be used: with CLASS=True the notebook picks its own "
                f"lecture sizes for {name} (FAST's or smaller). Run without CLASS=True to use it, or drop -p {name}")
    if mode == "FAST" and spec.fast is not None:
        return (f"{stem}: {name}={value!r} would not be used: with FAST=True the notebook {spec.fast}. "
                f"Run without --quick / FAST=True to use it, or drop -p {name}")
    if mode == "FAST" and spec.fast_cap is not None and (value is None or value > spec.fast_cap):
        return (f"{stem}: {name}={value!r} would not be used: with FAST=True the notebook lowers {name} to "
                f"{_fmt(spec.fast_cap)}. Run without --quick / FAST=True, or give at most {_fmt(spec.fast_cap)}")
    return None
