"""The settings tables of the LIAS planar UWB READMEs: anchors, tag offsets and static poses.

``Static/README.md`` has one section per day, ``Dynamic/README.md`` a single set of tables
(:func:`read_tables`); the loaders of :mod:`uwbwb.datasets.lias` build their anchors, tag
offsets and static poses from them.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import DataFormatError, DataNotFoundError
from ..types import Anchors
from .text import NUMBER_RE, _read_bytes

__all__ = ["LiasTables", "read_tables"]

_SESSION_RE = re.compile(r"(\d{1,2})\.(\d{1,2})")
_DATE_HEADING_RE = re.compile(r"(#{1,6})\s*(\d{4})\s*/\s*(\d{1,2})\s*/\s*(\d{1,2})\s*")


@dataclass(frozen=True)
class LiasTables:
    """The settings tables of one README section.

    Attributes
    ----------
    readme
        The README they were read from.
    session
        Static session (``"8.14"``) or None for a README without date sections.
    line
        First line of the section.
    anchors
        Anchors ``a0`` ... in the global frame, metres.
    tag_ids
        ``("t0", "t1", ...)``.
    tag_offsets_m
        Tag positions in the trolley (body) frame, shape ``(n_tags, 3)``, metres.
    poses
        Static pose table (columns ``site, yaw_deg, x_m, y_m, line``), or None when the
        section has none.
    """

    readme: Path
    session: str | None
    line: int
    anchors: Anchors
    tag_ids: tuple[str, ...]
    tag_offsets_m: np.ndarray
    poses: pd.DataFrame | None = None


@dataclass(frozen=True)
class _MdTable:
    first_line: int
    header: list[str]
    rows: list[tuple[int, list[str]]]


def _md_cells(line: str) -> list[str]:
    s = line.strip()
    s = s[1:] if s.startswith("|") else s
    s = s[:-1] if s.endswith("|") else s
    return [c.strip() for c in s.split("|")]


def _is_rule(cells: list[str]) -> bool:
    """The ``| --- | :-: |`` line under a markdown table header."""
    return any(cells) and all(re.fullmatch(r":?-+:?", c) for c in cells if c)


def _md_tables(lines: list[str], start: int, stop: int) -> list[_MdTable]:
    """Markdown tables among ``lines[start:stop]`` (0-based), with 1-based line numbers."""
    tables, i = [], start
    while i < stop:
        if not lines[i].lstrip().startswith("|"):
            i += 1
            continue
        j = i
        while j < stop and lines[j].lstrip().startswith("|"):
            j += 1
        block = [(k + 1, _md_cells(lines[k])) for k in range(i, j)]
        body = [row for row in block[1:] if not _is_rule(row[1])]
        tables.append(_MdTable(i + 1, block[0][1], body))
        i = j
    return tables


def _sections(readme: Path, lines: list[str]) -> dict[str, tuple[int, int]]:
    """Date sections ``### YYYY/M/D`` -> ``{"M.D": (start, stop)}`` (0-based line range)."""
    heads = []
    for i, ln in enumerate(lines):
        m = re.match(r"(#{1,6})\s", ln)
        if m:
            heads.append((i, len(m.group(1)), _DATE_HEADING_RE.fullmatch(ln.strip())))
    out: dict[str, tuple[int, int]] = {}
    for k, (i, level, date) in enumerate(heads):
        if date is None:
            continue
        stop = next((j for j, lv, _ in heads[k + 1:] if lv <= level), len(lines))
        session = f"{int(date.group(3))}.{int(date.group(4))}"
        if session in out:
            raise DataFormatError(readme, f"two sections for session {session}", line=i + 1)
        out[session] = (i, stop)
    return out


def _numbers(readme: Path, line: int, cells: list[str], names: list[str]) -> list[float]:
    out = []
    for c, name in zip(cells, names):
        v = float(c) if re.fullmatch(NUMBER_RE, c) else np.nan
        if not np.isfinite(v):
            raise DataFormatError(readme, f"{c!r} is not a number", line=line, column=name)
        out.append(v)
    return out


def _axes_ok(header: list[str], axes: str) -> bool:
    found = ["".join(ch for ch in cell if ch in "XYZ") for cell in header[1:1 + len(axes)]]
    return found == list(axes)


def _labelled_table(readme: Path, tables: list[_MdTable], label: str, what: str,
                    where: str, section_line: int) -> tuple[list[str], np.ndarray]:
    """Rows ``'<label> k' | x | y | z`` of the one table whose rows carry ``label``."""
    pat = re.compile(rf"{label}\s*(\d+)", re.IGNORECASE)
    hits = [t for t in tables if any(pat.fullmatch(r[1][0]) for r in t.rows if r[1])]
    if not hits:
        raise DataFormatError(readme, f"{where} has no {what} table (rows '{label} 0', "
                                      f"'{label} 1', ...)", line=section_line)
    if len(hits) > 1:
        raise DataFormatError(readme, f"{where} has more than one {what} table", line=hits[1].first_line)
    table = hits[0]
    if len(table.header) != 4 or not _axes_ok(table.header, "XYZ"):
        raise DataFormatError(readme, f"{what} table header {table.header}; expected a label "
                                      f"column then X, Y, Z (m)", line=table.first_line)
    index, pos = [], []
    for line, cells in table.rows:
        m = pat.fullmatch(cells[0]) if cells else None
        if m is None or len(cells) != 4:
            raise DataFormatError(readme, f"{what} table row {cells}; expected '{label} k | x | y | z'",
                                  line=line)
        index.append(int(m.group(1)))
        pos.append(_numbers(readme, line, cells[1:], ["X", "Y", "Z"]))
    if sorted(index) != list(range(len(index))):
        raise DataFormatError(readme, f"{what} numbers {index}; expected 0 ... {len(index) - 1}, "
                                      f"each once", line=table.first_line)
    order = np.argsort(index)
    return [str(index[k]) for k in order], np.asarray(pos, float)[order]


def _pose_table(readme: Path, tables: list[_MdTable], where: str) -> pd.DataFrame | None:
    hits = [t for t in tables if t.header and re.fullmatch(r"poses?", t.header[0], re.IGNORECASE)]
    if not hits:
        return None
    if len(hits) > 1:
        raise DataFormatError(readme, f"{where} has more than one pose table", line=hits[1].first_line)
    table = hits[0]
    if len(table.header) != 4 or "yaw" not in table.header[1].lower() or not _axes_ok(
            [""] + table.header[2:], "XY"):
        raise DataFormatError(readme, f"pose table header {table.header}; expected "
                                      f"'Poses | Yaw(deg) | X (m) | Y (m)'", line=table.first_line)
    rows, site = [], None
    for line, cells in table.rows:
        if len(cells) != 4:
            raise DataFormatError(readme, f"pose table row has {len(cells)} cells, expected 4", line=line)
        if cells[0]:
            m = re.fullmatch(r"pose\s*(\d+)", cells[0], re.IGNORECASE)
            if m is None:
                raise DataFormatError(readme, f"pose label {cells[0]!r}; expected 'Pose k' or empty",
                                      line=line)
            site = int(m.group(1))
            if not any(cells[1:]):
                continue  # "Pose k" on a row of its own; its poses follow
        if site is None:
            raise DataFormatError(readme, "pose values before any 'Pose k' label", line=line)
        yaw, x, y = _numbers(readme, line, cells[1:], ["Yaw", "X", "Y"])
        rows.append((site, yaw, x, y, line))
    if not rows:
        raise DataFormatError(readme, "pose table has no poses", line=table.first_line)
    return pd.DataFrame(rows, columns=["site", "yaw_deg", "x_m", "y_m", "line"])


def _parse_session(session: str) -> str:
    m = _SESSION_RE.fullmatch(str(session).strip())
    if m is None:
        raise ValueError(f"session must look like '8.14' (month.day), got {session!r}")
    return f"{int(m.group(1))}.{int(m.group(2))}"


def read_tables(readme_path: str | os.PathLike, session: str | None = None) -> LiasTables:
    """Parse the anchor, tag-offset and (static) pose tables of an upstream README.

    ``Static/README.md`` has one section per day (``### 2022/8/14`` is session
    ``"8.14"``), each with its own tag, anchor and pose tables; ``Dynamic/README.md`` has
    a single set of tag and anchor tables and no sections. The pose table lists
    ``Pose k`` on the row of its first yaw (site 1) or on an empty row of its own (later
    sites), the following rows belonging to that site.

    Parameters
    ----------
    readme_path
        The README.md file.
    session
        ``"M.D"`` section to read: required for a README with date sections (Static),
        None for one without (Dynamic).

    Returns
    -------
    LiasTables

    Raises
    ------
    DataNotFoundError
        No such file.
    DataFormatError
        A missing section or table, or a garbled row, naming the README and line.
    ValueError
        ``session`` missing although the README has sections, or malformed.
    """
    readme = Path(readme_path)
    if not readme.is_file():
        raise DataNotFoundError(f"{readme} not found (it holds the anchor and tag tables)")
    text = _read_bytes(readme).decode("utf-8", errors="replace")
    if not text.strip():
        raise DataFormatError(readme, "README is empty (expected the settings tables)", line=1)
    lines = text.splitlines()
    sections = _sections(readme, lines)
    if session is None:
        if sections:
            raise ValueError(f"{readme} has one section per session ({', '.join(sections)}); "
                             f"pass session=")
        start, stop, where = 0, len(lines), "the README"
    else:
        session = _parse_session(session)
        if session not in sections:
            raise DataFormatError(readme, f"no section '### YYYY/{session.replace('.', '/')}' for "
                                          f"session {session}; sections found: "
                                          f"{', '.join(sections) or 'none'}")
        start, stop = sections[session]
        where = f"section '{lines[start].strip()}'"
    tables = _md_tables(lines, start, stop)
    tag_idx, offsets = _labelled_table(readme, tables, "Tag", "tag", where, start + 1)
    anchor_idx, anchor_pos = _labelled_table(readme, tables, "Anchor", "anchor", where, start + 1)
    poses = _pose_table(readme, tables, where)
    offsets.setflags(write=False)
    return LiasTables(readme, session, start + 1,
                      Anchors(tuple(f"a{i}" for i in anchor_idx), anchor_pos),
                      tuple(f"t{i}" for i in tag_idx), offsets, poses)
