"""Exceptions raised by uwbwb."""

from __future__ import annotations

from pathlib import Path


class DataFormatError(ValueError):
    """A data file does not match the format its loader expects.

    Parameters
    ----------
    path
        The offending file.
    problem
        What was found and what was expected, in plain words.
    line
        1-based line number in the file, when the problem is on one line.
    column
        Column name or 1-based index, when known.

    The message is bounded: a problem longer than :data:`MAX_PROBLEM_CHARS`
    (e.g. quoting a line of a file whose line ends were not recognised) is cut,
    saying how long it was; the full text stays in :attr:`problem`.
    """

    #: Longest problem text put into the message.
    MAX_PROBLEM_CHARS = 400

    def __init__(self, path: str | Path, problem: str, line: int | None = None,
                 column: str | int | None = None):
        self.path = Path(path)
        self.problem = problem
        self.line = line
        self.column = column
        where = str(self.path)
        if line is not None:
            where += f", line {line}"
        if column is not None:
            where += f", column {column}"
        shown = problem
        if len(shown) > self.MAX_PROBLEM_CHARS:
            shown = f"{shown[:self.MAX_PROBLEM_CHARS]}... [message cut: {len(problem)} characters]"
        super().__init__(f"{where}: {shown}")


class DataNotFoundError(FileNotFoundError):
    """A dataset or recording could not be found in any data directory."""


class GeometryError(ValueError):
    """The anchor/measurement geometry does not determine a position."""
