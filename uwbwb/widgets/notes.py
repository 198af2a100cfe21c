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


@dataclass(frozen=True)
class ExerciseCheck:
    """Outcome of an exercise's check: the predicted direction, whether it held, and the numbers.

    An exercise asks "change X, predict Y"; the experiment package computes both settings
    and returns one of these. The notebook's check cell is ``assert check.holds, check``
    followed by ``check`` (shown as one line of Markdown).

    Attributes
    ----------
    claim
        The direction asserted, e.g. ``"PF error above KF error"``.
    holds
        Whether the run shows it.
    numbers
        ``{name: value}`` the verdict was computed from, with units in the names.
    """

    claim: str
    holds: bool
    numbers: Mapping[str, float]

    def __post_init__(self):
        object.__setattr__(self, "holds", bool(self.holds))
        object.__setattr__(self, "numbers", MappingProxyType(dict(self.numbers)))

    def __str__(self) -> str:
        nums = ", ".join(f"{k} = {_format_number(float(v))}" for k, v in self.numbers.items())
        return f"{'holds' if self.holds else 'DOES NOT HOLD'}: {self.claim} ({nums})"

    def _repr_markdown_(self) -> str:
        nums = ", ".join(f"{k} = {_format_number(float(v))}" for k, v in self.numbers.items())
        mark = "✔ check holds" if self.holds else "✘ check does not hold"
        return f"**{mark}:** {self.claim} — {nums}"
