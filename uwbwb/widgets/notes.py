"""Teaching notes under the panels: the data banner, "what you should see" and the exercise check (see :mod:`uwbwb.widgets`)."""

from __future__ import annotations

import html
from dataclasses import dataclass
from collections.abc import Mapping
from types import MappingProxyType

from .panel import _format_number


# --------------------------------------------------------------------------- data banner

_BANNER_STYLE = {
    True: "background:#e3f1e3;border:1px solid #4a8;padding:6px",
    False: "background:#fde2e1;border:2px solid #c0392b;padding:8px;font-weight:bold",
}


def data_banner(dataset: str, found: bool, *, detail: str = "", instead: str = "this section is skipped"):
    """The one banner every notebook shows about its real data, for ``IPython.display.display``.

    Parameters
    ----------
    dataset
        Dataset name, e.g. ``"lias-planar-uwb"``.
    found
        Whether the real data was found and is used: a quiet green line; otherwise a
        conspicuous red box that says what happens instead and how to get the data.
    detail
        What was used (when found) or why it is missing (when not), one sentence.
    instead
        When not found: what the notebook does instead (``"this section is skipped"``,
        ``"a synthetic stand-in is shown"``, ...).

    Returns
    -------
    IPython.display.HTML
        Its text is escaped; the element carries CSS class ``uwbwb-data-banner``.
    """
    from IPython.display import HTML

    name = html.escape(dataset)
    if found:
        text = f"Real data <b>{name}</b> found" + (f": {html.escape(detail)}" if detail else ".")
    else:
        why = f" ({html.escape(detail)})" if detail else ""
        text = (f"Real data {name} is not available on this machine{why}: {html.escape(instead)}. "
                f"Get it with <code>python -m uwbwb fetch {name}</code> or set DATA_DIR.")
    return HTML(f'<div class="uwbwb-data-banner" style="{_BANNER_STYLE[bool(found)]}">{text}</div>')


# --------------------------------------------------------------------------- teaching notes

#: Longest "what you should see" note (characters): about three lines of a notebook.
SEE_MAX_CHARS = 420


def what_you_should_see(text: str):
    """The short note under a panel or figure that tells a student what to look at.

    Parameters
    ----------
    text
        At most three lines and :data:`SEE_MAX_CHARS` characters of Markdown; numbers in it
        should be computed from the run (f-strings), not typed in.

    Returns
    -------
    IPython.display.Markdown
        ``**What you should see.** text``, for ``IPython.display.display`` (or as a cell's value).

    Raises
    ------
    ValueError
        Empty text, more than three lines, or longer than :data:`SEE_MAX_CHARS`.
    """
    from IPython.display import Markdown

    lines = [ln for ln in str(text).strip().splitlines() if ln.strip()]
    if not lines:
        raise ValueError("text: a 'what you should see' note needs some text")
    if len(lines) > 3 or len(str(text).strip()) > SEE_MAX_CHARS:
        raise ValueError(f"text: a 'what you should see' note has at most 3 lines and {SEE_MAX_CHARS} characters, "
                         f"got {len(lines)} lines and {len(str(text).strip())} characters")
    return Markdown("**What you should see.** " + " ".join(ln.strip() for ln in lines))


#: How a check says that a prediction is what the run shows (the answer key's audit reads it:
#: :func:`uwbwb.classroom.wrong_predictions`).
RIGHT = "✔ Right"


@dataclass(frozen=True)
class ExerciseCheck:
    """What an exercise's run shows, and the student's prediction read against it.

    An exercise asks "change X, predict Y" and offers two answers: ``choices[0]`` is the claim, ``choices[1]``
    its opposite. The experiment package computes both settings and returns one of these; the run's
    ``outcome`` is the choice its numbers support. The notebook's check cell is::

        check = <exercise>(...)
        assert check.holds, check            # the notebook's text states the claim: a flip fails the run
        check.against(PREDICTION_1, reveal=not CLASS)

    Attributes
    ----------
    claim
        The claim as a sentence, e.g. ``"PF error above KF error"``.
    holds
        Whether the run shows it.
    numbers
        ``{name: value}`` the verdict was computed from, with units in the names.
    choices
        ``(the claim, its opposite)`` as a student writes them, e.g. ``("higher", "not higher")``.
    why
        The reason, written by hand in the exercise's function; shown once the student has predicted.
    """

    claim: str
    holds: bool
    numbers: Mapping[str, float]
    choices: tuple[str, str]
    why: str = ""

    def __post_init__(self):
        object.__setattr__(self, "holds", bool(self.holds))
        object.__setattr__(self, "numbers", MappingProxyType(dict(self.numbers)))
        choices = tuple(str(c) for c in self.choices)
        if len(choices) != 2 or choices[0] == choices[1]:
            raise ValueError(f"choices: two different answers (the claim, its opposite), got {self.choices!r}")
        object.__setattr__(self, "choices", choices)

    @property
    def outcome(self) -> str:
        """The choice the run shows."""
        return self.choices[0] if self.holds else self.choices[1]

    def _numbers(self) -> str:
        return ", ".join(f"{k} = {_format_number(float(v))}" for k, v in self.numbers.items())

    def __str__(self) -> str:
        return f"{'holds' if self.holds else 'DOES NOT HOLD'}: {self.claim} ({self._numbers()})"

    def _repr_markdown_(self) -> str:
        mark = "✔ check holds" if self.holds else "✘ check does not hold"
        return f"**{mark}:** {self.claim} — {self._numbers()}"

    def against(self, prediction: str | None, *, reveal: bool = False) -> "PredictionCheck":
        """The student's ``prediction`` (one of :attr:`choices`, or None before they write one) read against the
        run. With None the result asks for a prediction and shows no number, unless ``reveal`` (a research run,
        where nobody predicts). The answer key (``make class``) writes the claim, ``choices[0]``, and reads "right"; the error for a
        prediction that is not a choice lists them sorted, not claim first.

        Raises
        ------
        ValueError
            A prediction that is not one of the choices (the message lists them).
        """
        if prediction is not None and prediction not in self.choices:
            raise ValueError(f"PREDICTION: write one of {sorted(self.choices)} (as a string), or None; "
                             f"got {prediction!r}")
        return PredictionCheck(self, prediction, bool(reveal))


@dataclass(frozen=True, repr=False)
class PredictionCheck:
    """A prediction read against an :class:`ExerciseCheck` (:meth:`ExerciseCheck.against`); shown as Markdown,
    and its ``repr`` (a notebook's text/plain output) is the same text, so no number shows before a prediction."""

    check: ExerciseCheck
    prediction: str | None
    reveal: bool = False

    @property
    def right(self) -> bool | None:
        """Whether the prediction is what the run shows (None: no prediction)."""
        if self.prediction is None:
            return None
        return self.prediction == self.check.outcome

    def _repr_markdown_(self) -> str:
        c = self.check
        options = " or ".join(f'`"{x}"`' for x in c.choices)
        if self.prediction is None and not self.reveal:
            return (f"**Write your prediction first**: set `PREDICTION_…` in the cell above to {options}, "
                    "then run this cell again; it says whether the run agrees, why, and shows the numbers.")
        if self.prediction is None:
            head = f"**No prediction written.** The run shows **{c.outcome}**"
        elif self.right:
            head = f"**{RIGHT}:** you predicted {self.prediction!r} and the run shows **{c.outcome}**"
        else:
            head = f"**✘ Not what the run shows:** you predicted {self.prediction!r}; the run shows **{c.outcome}**"
        why = f" {c.why}" if c.why else ""
        return f"{head} ({c.claim}: {'holds' if c.holds else 'does not hold'}).{why}\n\nNumbers: {c._numbers()}"

    __repr__ = _repr_markdown_
