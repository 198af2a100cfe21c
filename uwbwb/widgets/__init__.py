"""Interactive panels for the notebooks: controls, a readout and a figure.

Every notebook ends with one or more :class:`Panel`\\ s. A panel is a set of
named controls and a ``render`` function that recomputes the experiment from
the control values and returns what to show::

    import functools
    import uwbwb as uw

    @functools.lru_cache(maxsize=32)          # values are hashable: cache per setting
    def run(sigma_m, n_anchors, seed):
        cfg = dataclasses.replace(BASE_CONFIG, sigma_m=sigma_m, n_anchors=n_anchors)
        return uw.experiments.paper.run(cfg, rng=np.random.default_rng(seed))

    def render(sigma_m, n_anchors, seed):
        result = run(sigma_m, n_anchors, seed)
        fig, ax = plt.subplots()
        uw.plotting.error_cdf(result, ax=ax)
        return fig, {"RMSE (cm)": 100 * result.rmse_m}

    panel = uw.widgets.Panel("Error CDF", {
        "sigma_m": uw.widgets.float_slider("σ", 0.1, 0.01, 1.0, 0.01, unit="m"),
        "n_anchors": uw.widgets.int_slider("anchors", 4, 3, 8),
        "seed": uw.widgets.seed_box(0),
    }, render)
    panel                                      # or display(panel)

``render`` may return a matplotlib ``Figure``, a readout (headline numbers), or
a tuple ``(figure, readout)``. A readout is a ``str`` (shown as plain,
pre-formatted text), a mapping ``{name: value}`` (shown as a two-column table,
floats with 4 significant digits) or any object with ``_repr_html_`` such as
``IPython.display.HTML`` or a small ``pandas.DataFrame``.

The panel renders once when it is created, so it also works headless (papermill,
tests); an exception from that first render propagates, so a notebook whose
panel cannot draw fails like any other cell. Afterwards every control change
re-renders. Exceptions from those renders do not disappear into the kernel log:
the panel shows them in an element with CSS class ``uwbwb-error`` (panel title
and the exception's last traceback line, the full traceback folded below) and
keeps the exception in :attr:`Panel.last_error`.

Figures are converted to PNG and closed immediately, and so is every other
pyplot figure the render function opened, so panels never leak open figures.

DOM classes, for styling and for the browser test: the panel is a ``VBox`` with
class ``uwbwb-panel``; inside it ``uwbwb-title``, ``uwbwb-controls``,
``uwbwb-error`` (only while an error is shown), ``uwbwb-readout`` (an ``HTML``)
and ``uwbwb-figure`` (an ``Output``).

Modules: :mod:`.panel` (controls, readouts, :class:`PanelFigure`, :class:`Panel`) and
:mod:`.notes` (the teaching notes :func:`data_banner`, :func:`what_you_should_see`,
:class:`ExerciseCheck`); every name importable from here.
"""

from .notes import SEE_MAX_CHARS, ExerciseCheck, PredictionCheck, data_banner, what_you_should_see  # noqa: F401 (SEE_MAX_CHARS: tests)
from .panel import Panel, PanelFigure, dropdown, float_slider, int_slider, seed_box


__all__ = ["Panel", "PanelFigure", "float_slider", "int_slider", "dropdown", "seed_box", "data_banner",
           "ExerciseCheck", "PredictionCheck", "what_you_should_see"]
