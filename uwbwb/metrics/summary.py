"""The reproduction summary table (:class:`Summary`) and a summary row declared as data (:class:`Headline`)."""

from __future__ import annotations

import json
import math
import numbers
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

def _real(value, what: str, *, allow_none: bool = False) -> float | None:
    if value is None and allow_none:
        return None
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ValueError(f"{what} must be a real number, got {value!r}")
    v = float(value)
    if allow_none and math.isnan(v):
        return None
    if not math.isfinite(v):
        raise ValueError(f"{what} must be finite, got {value!r}")
    return v


class Summary:
    """Headline numbers of one notebook, for the reproduction report.

    Every row says what kind of number it is and which mode produced it:

    ``kind``
        ``"reproduced"`` — came out of the method; ``"target"`` — a simulator
        parameter was chosen to hit it (agreement with the paper is by
        construction); ``"input"`` — taken from the paper (or follows directly
        from a value taken from it); ``"assumption"`` — a setting the paper does
        not give, chosen by us (see the glossary).
    ``mode``
        ``"FAST"`` (small CI-sized experiments: smoke-test numbers) or ``"full"``.

    Parameters
    ----------
    notebook
        Notebook name, e.g. ``"00_quickstart"``.
    fast
        The notebook's ``FAST`` parameter: the mode of every row.

    Examples
    --------
    >>> s = Summary("00_quickstart", fast=False)
    >>> s.add(quantity="CEP95, tag t0, raw multilateration", value=0.31, unit="m",
    ...       paper_value=None, data="lias-planar-uwb/fast", kind="reproduced")
    >>> list(s.frame().columns)
    ['notebook', 'quantity', 'value', 'unit', 'paper_value', 'data', 'kind', 'mode']
    >>> s.frame()["mode"].tolist()
    ['full']
    """

    COLUMNS = ("notebook", "quantity", "value", "unit", "paper_value", "data", "kind", "mode")
    #: Allowed values of ``kind``.
    KINDS = ("reproduced", "target", "input", "assumption")
    #: Allowed values of ``mode``: under ``FAST=True`` and otherwise.
    MODES = ("FAST", "full")

    def __init__(self, notebook: str, *, fast: bool):
        if not isinstance(notebook, str) or not notebook.strip():
            raise ValueError(f"notebook must be a non-empty string, got {notebook!r}")
        if not isinstance(fast, (bool, np.bool_)):
            raise ValueError(f"fast must be True or False (the notebook's FAST parameter), got {fast!r}")
        self.notebook = notebook
        self.mode = "FAST" if fast else "full"
        self._rows: list[dict] = []

    def __len__(self) -> int:
        return len(self._rows)

    def __repr__(self) -> str:
        return f"Summary({self.notebook!r}, {len(self)} rows, mode {self.mode})"

    def add(self, *, quantity: str, value, unit: str, data: str, kind: str, paper_value=None) -> None:
        """Record one headline number.

        Parameters
        ----------
        quantity
            What was measured, specific enough to be unique with ``data``
            (e.g. ``"CEP95, tag t0, raw multilateration"``).
        value
            The value: a finite real number (numpy scalars accepted).
        unit
            Unit of ``value`` and ``paper_value`` (e.g. ``"m"``, ``"cm"``, ``"%"``, ``""``).
        data
            ``"synthetic"`` or ``"dataset/recording"`` (e.g. ``Recording.label``).
        kind
            ``"reproduced"``, ``"target"``, ``"input"`` or ``"assumption"`` (see the class docstring).
        paper_value
            The value the paper reports, or None (NaN is read as None).

        Raises
        ------
        ValueError
            On an invalid field or a repeated ``(quantity, data)`` pair.
        """
        if not isinstance(quantity, str) or not quantity.strip():
            raise ValueError(f"quantity must be a non-empty string, got {quantity!r}")
        v = _real(value, f"value of {quantity!r}")
        pv = _real(paper_value, f"paper_value of {quantity!r}", allow_none=True)
        if not isinstance(unit, str):
            raise ValueError(f"unit of {quantity!r} must be a string, got {unit!r}")
        if not isinstance(data, str) or not (data == "synthetic" or _is_recording_label(data)):
            raise ValueError(f"data of {quantity!r} must be 'synthetic' or 'dataset/recording', got {data!r}")
        if kind not in self.KINDS:
            raise ValueError(f"kind of {quantity!r} must be one of {', '.join(self.KINDS)}, got {kind!r}")
        if any(r["quantity"] == quantity and r["data"] == data for r in self._rows):
            raise ValueError(f"{self.notebook}: quantity {quantity!r} on data {data!r} was already added")
        self._rows.append({"notebook": self.notebook, "quantity": quantity, "value": v, "unit": unit,
                           "paper_value": pv, "data": data, "kind": kind, "mode": self.mode})

    def frame(self) -> pd.DataFrame:
        """The rows as a DataFrame with exactly :attr:`COLUMNS` (``paper_value`` NaN where None)."""
        df = pd.DataFrame(self._rows, columns=list(self.COLUMNS))
        return df.astype({"value": float, "paper_value": float})

    def publish(self, path: str | os.PathLike | None = None) -> pd.DataFrame:
        """Return :meth:`frame` and, if ``path`` is given, also write the rows there.

        The file is a JSON list of objects with the keys of :attr:`COLUMNS`,
        missing ``paper_value`` written as ``null``. Parent directories are created.
        Writing an empty summary is a ValueError (the report needs at least one row).
        """
        if path is not None:
            if not self._rows:
                raise ValueError(f"{self.notebook}: nothing to publish (no rows were added)")
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(self._rows, indent=2, allow_nan=False) + "\n", encoding="utf-8")
        return self.frame()


def interval_rows(quantity: str, value: float, lo: float, hi: float, **row) -> list[dict]:
    """Summary rows (keyword arguments of :meth:`Summary.add`) of a number and, where both ends are finite, the ends
    of its 95 % interval beside it (``<quantity>, 95 % low`` / ``high``); ``row`` (unit, data, kind, ...) goes to
    each."""
    ends = [(", 95 % low", lo), (", 95 % high", hi)] if np.isfinite(lo) and np.isfinite(hi) else []
    return [dict(quantity=quantity + suffix, value=v, **row) for suffix, v in [("", value), *ends]]


def interval_text(lo: float, hi: float, fmt: str = ".3g", *, none: str = "—") -> str:
    """An interval as a table or a figure shows it, ``"[lo, hi]"`` with both ends in format ``fmt``; ``none`` where
    either end is not finite (no interval)."""
    return f"[{lo:{fmt}}, {hi:{fmt}}]" if np.isfinite(lo) and np.isfinite(hi) else none


def _is_recording_label(data: str) -> bool:
    dataset, _, recording = data.partition("/")
    return bool(dataset.strip()) and bool(recording.strip())


@dataclass(frozen=True)
class Headline:
    """One summary row declared as data: what it is, and how to read its value from an
    experiment's ``facts`` dict (each experiment's ``headlines.py`` lists its rows as these).

    Attributes
    ----------
    quantity, unit
        As in :meth:`Summary.add`.
    kind
        One of :attr:`Summary.KINDS`: *reproduced*, *target*, *input* or *assumption*.
    read
        ``facts → value``.
    paper
        The paper's value where one is comparable (None otherwise).
    """

    quantity: str
    unit: str
    kind: str
    read: Callable[[dict], float]
    paper: float | None = None

    def __post_init__(self):
        if self.kind not in Summary.KINDS:
            raise ValueError(f"Headline.kind must be one of {', '.join(Summary.KINDS)}, got {self.kind!r}")

    def row(self, facts: dict, *, data: str = "synthetic") -> dict:
        """Keyword arguments of :meth:`Summary.add` for this headline, read from ``facts``."""
        return {"quantity": self.quantity, "value": float(self.read(facts)), "unit": self.unit,
                "paper_value": self.paper, "kind": self.kind, "data": data}
