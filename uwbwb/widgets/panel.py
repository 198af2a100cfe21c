"""Interactive panels: controls, readouts, a reused figure and the :class:`Panel` (see :mod:`uwbwb.widgets`)."""

from __future__ import annotations

import base64
import html
import io
import math
import traceback
from collections.abc import Callable, Mapping, Sequence
from decimal import Decimal
from html.parser import HTMLParser
from types import MappingProxyType
from typing import Any

import ipywidgets as widgets
import matplotlib.pyplot as plt
from matplotlib.figure import Figure


#: Width of a control row; descriptions take their natural width inside it.
_CONTROL_LAYOUT = {"width": "34em"}
_CONTROL_STYLE = {"description_width": "initial"}


# --------------------------------------------------------------------------- controls

def _label(label: str, unit: str) -> str:
    return f"{label} ({unit})" if unit else label


def _check_in_range(label: str, value: float, lo: float, hi: float) -> None:
    if not lo <= hi:
        raise ValueError(f"{label!r}: min={lo!r} must not exceed max={hi!r}")
    if not lo <= value <= hi:
        raise ValueError(f"{label!r}: value {value!r} outside [{lo!r}, {hi!r}]")


def _decimals(*numbers: float) -> int:
    """Decimal places needed to print every number exactly (0.25 -> 2, 5.0 -> 0)."""
    exps = [Decimal(repr(float(x))).normalize().as_tuple().exponent for x in numbers]
    return max([0] + [-e for e in exps if isinstance(e, int)])


def float_slider(label: str, value: float, min: float, max: float, step: float, *,
                 log: bool = False, unit: str = "") -> widgets.FloatSlider | widgets.FloatLogSlider:
    """Slider for a real parameter, with the unit in its label.

    Parameters
    ----------
    label
        What the parameter is, e.g. ``"σ range"``.
    value, min, max
        Initial value and range, in ``unit``. The value must lie in the range
        (ipywidgets would otherwise clamp it silently).
    step
        Slider resolution: in ``unit`` for a linear slider, in decades (steps of
        ``log10(value)``) when ``log`` is true.
    log
        Logarithmic slider (``FloatLogSlider``); needs ``0 < min``.
    unit
        Unit shown in the label, e.g. ``"m"``; ``"label (unit)"``.

    Returns
    -------
    ipywidgets.FloatSlider or ipywidgets.FloatLogSlider
        With ``continuous_update=False``.
    """
    _check_in_range(label, value, min, max)
    if not step > 0:
        raise ValueError(f"{label!r}: step must be positive, got {step!r}")
    common = dict(description=_label(label, unit), value=value, step=step, continuous_update=False,
                  style=_CONTROL_STYLE, layout=widgets.Layout(**_CONTROL_LAYOUT))
    if log:
        if not min > 0:
            raise ValueError(f"{label!r}: a log slider needs min > 0, got {min!r}")
        return widgets.FloatLogSlider(min=math.log10(min), max=math.log10(max), base=10.0,
                                      readout_format=".3g", **common)
    return widgets.FloatSlider(min=min, max=max, readout_format=f".{_decimals(step, min)}f", **common)


def int_slider(label: str, value: int, min: int, max: int, step: int = 1, *,
               unit: str = "") -> widgets.IntSlider:
    """Slider for an integer parameter (counts, sizes), with the unit in its label.

    Parameters are as for :func:`float_slider`; ``value`` must lie in ``[min, max]``.
    """
    _check_in_range(label, value, min, max)
    if not step >= 1:
        raise ValueError(f"{label!r}: step must be >= 1, got {step!r}")
    return widgets.IntSlider(description=_label(label, unit), value=value, min=min, max=max,
                             step=step, continuous_update=False, style=_CONTROL_STYLE,
                             layout=widgets.Layout(**_CONTROL_LAYOUT))


def dropdown(label: str, options: Sequence[Any] | Mapping[str, Any], value: Any = None, *,
             unit: str = "") -> widgets.Dropdown:
    """Choice among named options (estimators, recordings, scenarios).

    Parameters
    ----------
    label
        What is chosen.
    options
        A sequence of values (shown with ``str``) or a mapping ``{shown label: value}``.
        Values are passed to ``render``, so keep them hashable for caching.
    value
        Initially selected value; the first option when ``None``.
    unit
        Unit shown in the label, if the options are quantities.
    """
    pairs = list(options.items()) if isinstance(options, Mapping) else [(str(o), o) for o in options]
    if not pairs:
        raise ValueError(f"{label!r}: no options")
    values = [v for _, v in pairs]
    if value is None:
        value = values[0]
    elif value not in values:
        raise ValueError(f"{label!r}: value {value!r} is not one of the options {values!r}")
    return widgets.Dropdown(description=_label(label, unit), options=pairs, value=value,
                            style=_CONTROL_STYLE, layout=widgets.Layout(**_CONTROL_LAYOUT))


def seed_box(value: int = 0) -> widgets.BoundedIntText:
    """Integer box for the seed of ``numpy.random.default_rng`` (0 … 2**31 - 1)."""
    _check_in_range("seed", value, 0, 2**31 - 1)
    return widgets.BoundedIntText(description="seed", value=value, min=0, max=2**31 - 1,
                                  continuous_update=False, style=_CONTROL_STYLE,
                                  layout=widgets.Layout(width="16em"))


def _bounds(control: widgets.Widget) -> tuple[float, float] | None:
    """Value range of a bounded control (where ipywidgets would clamp), else None."""
    if isinstance(control, widgets.FloatLogSlider):
        return control.base ** control.min, control.base ** control.max
    lo, hi = getattr(control, "min", None), getattr(control, "max", None)
    if isinstance(lo, (int, float)) and isinstance(hi, (int, float)):
        return lo, hi
    return None


# --------------------------------------------------------------------------- readouts

class _TextOfHTML(HTMLParser):
    """Plain text of an HTML fragment: cells separated by spaces, blocks by newlines."""

    _BLOCKS = {"p", "div", "tr", "br", "li", "pre", "table", "h1", "h2", "h3", "h4", "h5", "h6"}

    def __init__(self):
        super().__init__()
        self.parts: list[str] = []

    def handle_starttag(self, tag, attrs):
        if tag in self._BLOCKS:
            self.parts.append("\n")
        elif tag in ("td", "th"):
            self.parts.append(" ")

    def handle_data(self, data):
        self.parts.append(data)

    def text(self) -> str:
        lines = ("".join(self.parts)).splitlines()
        return "\n".join(" ".join(line.split()) for line in lines if line.strip())


def _html_to_text(fragment: str) -> str:
    parser = _TextOfHTML()
    parser.feed(fragment)
    parser.close()
    return parser.text()


def _format_number(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _readout_html(readout: Any) -> tuple[str, str]:
    """``(html, plain text)`` of a readout returned by a render function."""
    if readout is None:
        return "", ""
    if isinstance(readout, str):
        return f'<pre style="margin: 0; line-height: 1.4">{html.escape(readout)}</pre>', readout.strip()
    if isinstance(readout, Mapping):
        rows = "".join(f"<tr><th style='text-align: left; padding-right: 1em'>{html.escape(str(k))}</th>"
                       f"<td style='text-align: right'>{html.escape(_format_number(v))}</td></tr>"
                       for k, v in readout.items())
        text = "\n".join(f"{k}: {_format_number(v)}" for k, v in readout.items())
        return f"<table style='line-height: 1.4'>{rows}</table>", text
    to_html = getattr(readout, "_repr_html_", None)
    if callable(to_html):
        fragment = to_html()
        if isinstance(fragment, str):
            return fragment, _html_to_text(fragment)
    raise TypeError(f"a readout must be a str, a mapping or have _repr_html_, got {type(readout).__name__}")


def _split_result(result: Any) -> tuple[Figure | None, Any]:
    """``(figure, readout)`` from what a render function returned."""
    if isinstance(result, Figure):
        return result, None
    if isinstance(result, tuple):
        if len(result) == 2 and isinstance(result[0], Figure):
            return result
        raise TypeError("a render function returning a tuple must return (figure, readout), got "
                        f"({', '.join(type(r).__name__ for r in result)})")
    return None, result


def _png_output(fig: Figure) -> dict:
    """The figure as one notebook display_data output (PNG, tight bounding box)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", bbox_inches="tight")
    return {"output_type": "display_data",
            "data": {"image/png": base64.b64encode(buf.getvalue()).decode("ascii"),
                     "text/plain": repr(fig)},
            "metadata": {}}


# --------------------------------------------------------------------------- reused figure

class PanelFigure:
    """One figure for every render of a panel: axes, ticks and layout are built once, the data redrawn.

    A new figure per render pays for its axes, tick labels and ``tight_layout`` every time
    (most of a panel's drawing time). Instead a render function calls :meth:`clear`, draws
    into the returned axes with the usual plotting functions, and returns :meth:`done`::

        view = uw.widgets.PanelFigure(1, 2, figsize=(12, 4))

        def render(sigma_m):
            axes = view.clear()
            uw.plotting.error_cdf(run(sigma_m), ax=axes[0])
            ...
            return view.done(), readout

    :meth:`clear` removes the data artists (lines, patches, collections, texts, images, the
    legend), turns autoscaling back on and restarts the colour cycle; :meth:`done` rescales to the new data and lays the
    figure out on its first call only. The figure is not a pyplot figure, so the panel's
    closing of the figures a render opened leaves it alone.

    Parameters
    ----------
    nrows, ncols
        Grid of axes.
    figsize
        Inches, as for :func:`matplotlib.pyplot.subplots`.
    """

    def __init__(self, nrows: int = 1, ncols: int = 1, *, figsize=(6.4, 4.8)):
        self.figure = Figure(figsize=figsize)
        axes = self.figure.subplots(nrows, ncols, squeeze=False)
        self.axes = axes[0, 0] if axes.size == 1 else (axes.ravel() if 1 in axes.shape else axes)
        self._laid_out = False

    def clear(self):
        """Remove the previous render's data; returns the axes (one Axes, a 1-D array, or 2-D)."""
        for ax in self.figure.axes:
            for art in (*ax.lines, *ax.patches, *ax.collections, *ax.texts, *ax.images):
                art.remove()
            if ax.get_legend() is not None:
                ax.get_legend().remove()
            ax.set_autoscale_on(True)
            ax.set_prop_cycle(None)                  # default colours start over, as on a new axes
        return self.axes

    def done(self) -> Figure:
        """Rescale every axes to its new data (limits a plotting function set stay) and return the figure."""
        for ax in self.figure.axes:
            ax.relim()
            ax.autoscale_view()
        if not self._laid_out:
            self.figure.tight_layout()
            self._laid_out = True
        return self.figure


# --------------------------------------------------------------------------- panel

class Panel:
    """Controls, a readout and a figure that re-render on every control change.

    Parameters
    ----------
    title
        Shown above the controls and in error messages.
    controls
        ``{name: control}``; ``render`` is called with ``name=control.value`` for
        each. Controls with a ``continuous_update`` trait get it set to False, so
        the panel recomputes once when a slider is released, not while dragging.
    render
        ``render(**values)`` returning a ``Figure``, a readout, or ``(Figure, readout)``
        (see the module docstring). It should recompute from a frozen config built
        from the values; values are hashable, so the expensive part can be cached
        with :func:`functools.lru_cache`.

    Raises
    ------
    Exception
        Whatever the first render raises (after showing it in the panel).

    Attributes
    ----------
    widget : ipywidgets.VBox
        The whole panel (``display(panel)`` shows it).
    readout : ipywidgets.HTML
        Headline numbers.
    figure : ipywidgets.Output
        The figure, as one PNG output.
    error_box : ipywidgets.HTML
        The error display; a child of :attr:`widget` only while an error is shown.
    last_error : Exception or None
        Exception of the latest render, None after a successful one.
    render_count : int
        Number of times ``render`` has been called.
    """

    def __init__(self, title: str, controls: Mapping[str, widgets.ValueWidget],
                 render: Callable[..., Any]):
        if not controls:
            raise ValueError(f"panel {title!r} needs at least one control")
        for name, control in controls.items():
            if not name.isidentifier():
                raise ValueError(f"panel {title!r}: control name {name!r} is not a Python identifier")
            if not isinstance(control, widgets.ValueWidget):
                raise TypeError(f"panel {title!r}: control {name!r} is a {type(control).__name__}, "
                                "not an ipywidgets value widget")
        self.title = title
        self._controls = dict(controls)
        self._render_fn = render
        self.last_error: Exception | None = None
        self.render_count = 0
        self._readout_text = ""
        self._holding = False
        self._dirty = False

        self.readout = widgets.HTML()
        self.readout.add_class("uwbwb-readout")
        self.figure = widgets.Output()
        self.figure.add_class("uwbwb-figure")
        self.error_box = widgets.HTML()
        self.error_box.add_class("uwbwb-error")
        heading = widgets.HTML(f"<b>{html.escape(title)}</b>")
        heading.add_class("uwbwb-title")
        control_box = widgets.VBox(list(self._controls.values()))
        control_box.add_class("uwbwb-controls")
        self._children_ok = (heading, control_box, self.readout, self.figure)
        self.widget = widgets.VBox(self._children_ok)
        self.widget.add_class("uwbwb-panel")

        for control in self._controls.values():
            if "continuous_update" in control.trait_names():
                control.continuous_update = False
            control.observe(self._on_change, names="value")
        self._render(raise_errors=True)

    # ------------------------------------------------------------------ public API
    @property
    def controls(self) -> Mapping[str, widgets.ValueWidget]:
        """The controls by name (read-only mapping)."""
        return MappingProxyType(self._controls)

    @property
    def values(self) -> dict[str, Any]:
        """Current control values, as passed to ``render``."""
        return {name: control.value for name, control in self._controls.items()}

    @property
    def readout_text(self) -> str:
        """Plain text of the readout (empty while an error is shown)."""
        return self._readout_text

    def set(self, **values: Any) -> None:
        """Change controls as a user would, then re-render once if anything changed.

        All values are checked before any is applied: an unknown name or a value
        outside a slider's range raises ``ValueError`` (ipywidgets would clamp it
        silently) and leaves the panel as it was. Errors of the render itself are
        handled as for a user change: shown in the panel and kept on
        :attr:`last_error`.
        """
        unknown = sorted(set(values) - set(self._controls))
        if unknown:
            raise ValueError(f"panel {self.title!r} has no control {', '.join(map(repr, unknown))}; "
                             f"controls: {list(self._controls)}")
        for name, value in values.items():
            bounds = _bounds(self._controls[name])
            if bounds is not None and not bounds[0] <= value <= bounds[1]:
                raise ValueError(f"panel {self.title!r}: {name}={value!r} outside the control's "
                                 f"range [{bounds[0]!r}, {bounds[1]!r}]")
        self._holding, self._dirty = True, False
        try:
            for name, value in values.items():
                self._controls[name].value = value
        finally:
            self._holding = False
        if self._dirty:
            self._render()

    def _repr_mimebundle_(self, **kwargs):
        bundle = self.widget._repr_mimebundle_(**kwargs)
        # Front ends without widgets (saved papermill outputs, consoles) show the numbers.
        bundle["text/plain"] = "\n".join(filter(None, (self.title, self._readout_text)))
        return bundle

    def __repr__(self) -> str:
        return f"Panel({self.title!r}, controls={list(self._controls)}, render_count={self.render_count})"

    # ------------------------------------------------------------------ rendering
    def _on_change(self, change) -> None:
        if self._holding:
            self._dirty = True
        else:
            self._render()

    def _render(self, raise_errors: bool = False) -> None:
        self.render_count += 1
        open_before = set(plt.get_fignums())
        fig = None
        try:
            fig, readout = _split_result(self._render_fn(**self.values))
            readout_html, readout_text = _readout_html(readout)
            outputs = (_png_output(fig),) if fig is not None else ()
        except Exception as exc:  # shown in the panel, not lost in the kernel log
            self._show_error(exc)
            if raise_errors:
                raise
            return
        finally:
            for num in set(plt.get_fignums()) - open_before:
                plt.close(num)
            if fig is not None:
                plt.close(fig)
        self.last_error = None
        self._readout_text = readout_text
        with self.widget.hold_sync():
            self.readout.value = readout_html
            self.figure.outputs = outputs
            self.widget.children = self._children_ok

    def _show_error(self, exc: Exception) -> None:
        self.last_error = exc
        self._readout_text = ""
        last_line = traceback.format_exception_only(type(exc), exc)[-1].strip()
        full = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
        self.error_box.value = (
            f"<div style='color: #b00020; border-left: 3px solid #b00020; padding-left: 0.5em'>"
            f"<b>{html.escape(self.title)}</b> failed to render: <code>{html.escape(last_line)}</code>"
            f"<details><summary>traceback</summary><pre>{html.escape(full)}</pre></details></div>")
        with self.widget.hold_sync():
            self.readout.value = ""
            self.figure.outputs = ()
            heading, controls, readout, figure = self._children_ok
            self.widget.children = (heading, controls, self.error_box, readout, figure)
