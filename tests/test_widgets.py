"""Panels and control helpers, headless (no kernel, no browser)."""

from __future__ import annotations

import functools
import math

import ipywidgets as widgets
import matplotlib.pyplot as plt
import pytest
from IPython.display import HTML

from uwbwb import widgets as uww


def _classes(widget) -> tuple[str, ...]:
    return tuple(widget._dom_classes)


def _errors_in(panel) -> list:
    return [w for w in panel.widget.children if "uwbwb-error" in _classes(w)]


@pytest.fixture(autouse=True)
def no_leaked_figures():
    open_before = set(plt.get_fignums())
    yield
    leaked = set(plt.get_fignums()) - open_before
    plt.close("all")
    assert not leaked, f"figures left open: {sorted(leaked)}"


@pytest.fixture
def calls():
    return []


@pytest.fixture
def panel(calls):
    def render(gain, n, method):
        calls.append((gain, n, method))
        if method == "broken":
            raise RuntimeError(f"cannot render gain={gain}")
        fig, ax = plt.subplots()
        ax.plot(range(n), [gain * k for k in range(n)])
        return fig, {"gain": gain, "points": n, "method": method}

    return uww.Panel("Gain sweep", {
        "gain": uww.float_slider("gain", 0.5, 0.0, 2.0, 0.25, unit="m/s"),
        "n": uww.int_slider("points", 4, 2, 20),
        "method": uww.dropdown("method", ["plain", "broken"]),
    }, render)


def test_renders_once_on_creation(panel, calls):
    assert panel.render_count == 1
    assert calls == [(0.5, 4, "plain")]
    assert panel.last_error is None
    assert panel.readout_text == "gain: 0.5\npoints: 4\nmethod: plain"
    (output,) = panel.figure.outputs
    assert output["output_type"] == "display_data"
    assert output["data"]["image/png"].startswith("iVBORw0KGgo")  # base64 of the PNG magic


def test_dom_classes_and_layout(panel):
    assert "uwbwb-panel" in _classes(panel.widget)
    assert "uwbwb-readout" in _classes(panel.readout)
    assert "uwbwb-figure" in _classes(panel.figure)
    assert isinstance(panel.widget, widgets.VBox)
    assert panel.readout in panel.widget.children and panel.figure in panel.widget.children
    assert _errors_in(panel) == []


def test_set_renders_exactly_once_and_changes_readout(panel, calls):
    before_png = panel.figure.outputs[0]["data"]["image/png"]
    panel.set(gain=1.25, n=7)
    assert panel.render_count == 2
    assert calls[-1] == (1.25, 7, "plain")
    assert panel.readout_text == "gain: 1.25\npoints: 7\nmethod: plain"
    assert panel.figure.outputs[0]["data"]["image/png"] != before_png


def test_set_to_current_values_does_not_render(panel):
    panel.set(gain=0.5)
    assert panel.render_count == 1


def test_control_change_rerenders(panel, calls):
    panel.controls["n"].value = 9
    assert panel.render_count == 2
    assert calls[-1] == (0.5, 9, "plain")


def test_set_rejects_unknown_names_and_out_of_range_values(panel):
    with pytest.raises(ValueError, match="no control 'gian'"):
        panel.set(gian=1.0)
    with pytest.raises(ValueError, match=r"gain=3\.0 outside"):
        panel.set(n=5, gain=3.0)
    # nothing applied, nothing rendered: ipywidgets would have clamped gain to 2.0
    assert panel.values == {"gain": 0.5, "n": 4, "method": "plain"}
    assert panel.render_count == 1


def test_render_error_is_shown_and_kept(panel):
    panel.set(method="broken")
    assert isinstance(panel.last_error, RuntimeError)
    (box,) = _errors_in(panel)
    assert "Gain sweep" in box.value
    assert "RuntimeError: cannot render gain=0.5" in box.value
    assert panel.readout_text == "" and panel.figure.outputs == ()
    # fixed again: the error disappears
    panel.set(method="plain")
    assert panel.last_error is None
    assert _errors_in(panel) == []
    assert panel.readout_text.startswith("gain: 0.5")


def test_error_of_first_render_propagates():
    def render(x):
        plt.figure()  # opened before failing: must still be closed
        raise ValueError("bad config")

    with pytest.raises(ValueError, match="bad config"):
        uww.Panel("Broken", {"x": uww.int_slider("x", 1, 0, 3)}, render)


def test_figures_are_closed(panel):
    open_before = set(plt.get_fignums())
    for n in range(5, 10):
        panel.set(n=n)
    panel.set(method="broken")
    assert set(plt.get_fignums()) == open_before


def test_readout_kinds():
    def render(kind):
        return {"text": "RMSE 12.5 cm\nCEP95 30 cm",
                "html": HTML("<table><tr><td>RMSE</td><td>12.5 cm</td></tr></table>"),
                "figure": plt.figure()}[kind]

    p = uww.Panel("Kinds", {"kind": uww.dropdown("kind", ["text", "html", "figure"])}, render)
    assert p.readout_text == "RMSE 12.5 cm\nCEP95 30 cm"
    assert "<pre" in p.readout.value and "CEP95" in p.readout.value
    p.set(kind="html")
    assert p.readout_text == "RMSE 12.5 cm"
    p.set(kind="figure")
    assert p.readout_text == "" and len(p.figure.outputs) == 1


def test_text_is_escaped():
    p = uww.Panel("Escape", {"x": uww.int_slider("x", 1, 0, 3)}, lambda x: "a < b & c")
    assert "a &lt; b &amp; c" in p.readout.value


def test_bad_return_value_is_reported():
    def render(x):
        return (1, 2, 3) if x else "ok"

    p = uww.Panel("Tuple", {"x": uww.int_slider("x", 0, 0, 1)}, render)
    p.set(x=1)
    assert isinstance(p.last_error, TypeError)
    assert "(figure, readout)" in str(p.last_error)


def test_render_values_are_hashable_for_caching():
    @functools.lru_cache(maxsize=None)
    def compute(gain, seed):
        return gain * seed

    p = uww.Panel("Cached", {"gain": uww.float_slider("gain", 1.0, 0.0, 2.0, 0.5),
                             "seed": uww.seed_box(3)},
                  lambda gain, seed: f"{compute(gain, seed):.1f}")
    p.set(gain=2.0)
    p.set(gain=1.0)
    assert compute.cache_info().hits == 1 and compute.cache_info().misses == 2
    assert p.readout_text == "3.0"


def test_controls_do_not_update_continuously():
    text = widgets.IntText(value=1)  # continuous_update defaults to True here
    p = uww.Panel("Plain", {"k": text}, lambda k: str(k))
    assert text.continuous_update is False
    assert all(c.continuous_update is False for c in [
        uww.float_slider("a", 1.0, 0.0, 2.0, 0.1), uww.int_slider("b", 1, 0, 2), uww.seed_box(0)])
    assert p.render_count == 1


def test_panel_checks_its_controls():
    with pytest.raises(ValueError, match="needs at least one control"):
        uww.Panel("Empty", {}, lambda: "")
    with pytest.raises(TypeError, match="'x' is a Button"):
        uww.Panel("Button", {"x": widgets.Button()}, lambda x: "")
    with pytest.raises(ValueError, match="not a Python identifier"):
        uww.Panel("Name", {"a b": uww.int_slider("x", 1, 0, 2)}, lambda **kw: "")


def test_mimebundle_shows_widget_and_plain_text(panel):
    bundle = panel._repr_mimebundle_()
    assert bundle["text/plain"] == "Gain sweep\ngain: 0.5\npoints: 4\nmethod: plain"


def test_float_slider_label_range_and_format():
    s = uww.float_slider("σ range", 0.25, 0.0, 1.0, 0.05, unit="m")
    assert isinstance(s, widgets.FloatSlider)
    assert s.description == "σ range (m)"
    assert (s.min, s.max, s.step, s.value) == (0.0, 1.0, 0.05, 0.25)
    assert s.readout_format == ".2f"
    assert uww.float_slider("x", 2.0, 0.0, 10.0, 0.5).readout_format == ".1f"
    assert uww.float_slider("x", 20.0, 0.0, 100.0, 5.0).readout_format == ".0f"
    with pytest.raises(ValueError, match="outside"):
        uww.float_slider("x", 1.5, 0.0, 1.0, 0.1)
    with pytest.raises(ValueError, match="step"):
        uww.float_slider("x", 0.5, 0.0, 1.0, 0.0)


def test_log_slider():
    s = uww.float_slider("noise", 0.1, 1e-3, 10.0, 0.25, log=True, unit="m")
    assert isinstance(s, widgets.FloatLogSlider)
    assert math.isclose(s.base ** s.min, 1e-3) and math.isclose(s.base ** s.max, 10.0)
    assert s.value == pytest.approx(0.1) and s.step == 0.25
    with pytest.raises(ValueError, match="min > 0"):
        uww.float_slider("noise", 0.1, 0.0, 10.0, 0.25, log=True)
    p = uww.Panel("Log", {"noise": s}, lambda noise: f"{noise:.3g}")
    with pytest.raises(ValueError, match="outside"):
        p.set(noise=20.0)
    p.set(noise=5.0)
    assert p.readout_text == "5"


def test_int_slider_dropdown_seed_box():
    s = uww.int_slider("anchors", 4, 3, 8, unit="")
    assert (s.description, s.value, s.min, s.max) == ("anchors", 4, 3, 8)
    with pytest.raises(ValueError, match="outside"):
        uww.int_slider("anchors", 9, 3, 8)

    d = uww.dropdown("filter", {"Extended KF": "EKF", "Particle filter": "PF"}, "PF")
    assert d.value == "PF" and d.label == "Particle filter"
    assert uww.dropdown("rate", [10, 50], unit="Hz").value == 10
    with pytest.raises(ValueError, match="not one of the options"):
        uww.dropdown("filter", ["EKF", "PF"], "UKF")

    b = uww.seed_box(7)
    assert isinstance(b, widgets.BoundedIntText) and b.value == 7 and b.min == 0
    with pytest.raises(ValueError, match="outside"):
        uww.seed_box(-1)


def test_panel_figure_is_reused_and_redraws_the_new_data():
    import numpy as np

    view = uww.PanelFigure(1, 2, figsize=(6, 3))
    ymax = {"a": 1.0}

    def render(scale):
        axes = view.clear()
        axes[0].plot([0, 1, 2], [0, scale, 2 * scale], label="line")
        axes[0].axvspan(0.5, 1.0)
        axes[0].legend()
        axes[1].plot([0, 1], [0, 1])
        axes[1].set_ylim(0, ymax["a"])                     # a limit the plotting code sets stays
        return view.done(), {"scale": scale}

    open_before = set(plt.get_fignums())
    p = uww.Panel("reuse", {"scale": uww.float_slider("scale", 1.0, 1.0, 10.0, 1.0)}, render)
    first = p.figure.outputs[0]["data"]["image/png"]
    ax0, ax1 = view.axes
    assert len(ax0.lines) == 1 and len(ax0.patches) == 1 and ax0.get_legend() is not None
    p.set(scale=10.0)
    assert view.axes[0] is ax0 and len(ax0.lines) == 1 and len(ax0.patches) == 1   # nothing piles up
    assert ax0.get_ylim()[1] >= 20.0                       # rescaled to the new data
    assert ax1.get_ylim() == (0.0, 1.0)
    p.set(scale=1.0)
    assert ax0.get_ylim()[1] < 5.0                         # and back down: limits follow the data
    assert p.figure.outputs[0]["data"]["image/png"] == first   # the same picture for the same values
    assert set(plt.get_fignums()) == open_before
    np.testing.assert_array_equal(ax0.lines[0].get_ydata(), [0, 1.0, 2.0])
