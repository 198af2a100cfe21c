import subprocess
import sys

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.colors import to_hex  # noqa: E402

import uwbwb as uw  # noqa: E402
from uwbwb import metrics, plotting  # noqa: E402


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


ANCHORS = uw.Anchors(("a0", "a1", "a2", "a3"),
                     np.array([[0.0, 0.0, 2.0], [6.0, 0.0, 2.0], [6.0, 5.0, 2.0], [0.0, 5.0, 2.0]]))


def _lines(ax):
    return [ln for ln in ax.get_lines()]


def _legend_texts(ax):
    return [t.get_text() for t in ax.get_legend().get_texts()]


def test_colors_fixed_distinct_and_fallback_deterministic():
    assert plotting.color_for("truth") == "#000000"
    assert plotting.color_for("raw") == plotting.COLORS["raw"]
    for name in ("LS", "EKF", "EKF-RW", "EKF-RF", "EKF-RJ", "PF", "baseline PF", "set-noise PF",
                 "set-noise KF", "NLS", "INS", "ESKF", "calibrated", "uncalibrated", "UWB-only", "INS-only",
                 "loose", "tight", "tight (ranges)"):
        assert plotting.color_for(name) == plotting.COLORS[name]
    assert plotting.color_for("ekf-rw") == plotting.COLORS["EKF-RW"]
    assert len(set(plotting.COLORS.values())) == len(plotting.COLORS)
    c = plotting.color_for("my new filter")
    assert c == plotting.color_for("my new filter") and c not in plotting.COLORS.values()
    # Stable across interpreters (no salted hash()).
    out = subprocess.run([sys.executable, "-c", "import uwbwb.plotting as p; print(p.color_for('my new filter'))"],
                         capture_output=True, text=True, check=True)
    assert out.stdout.strip() == c


def test_import_leaves_rcparams_alone():
    code = ("import matplotlib as mpl; before = dict(mpl.rcParams); import uwbwb.plotting; "
            "after = dict(mpl.rcParams); print(before == after)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "True"


def test_floor_plan():
    ax = plotting.floor_plan(ANCHORS)
    assert isinstance(ax, Axes)
    assert [t.get_text() for t in ax.texts] == ["a0", "a1", "a2", "a3"]
    assert len(_lines(ax)) == 1 and len(_lines(ax)[0].get_xdata()) == 4
    assert ax.get_aspect() == 1.0
    assert ax.get_xlabel() == "x (m)" and ax.get_ylabel() == "y (m)"
    _, ax2 = plt.subplots()
    assert plotting.floor_plan(ANCHORS.pos_m[:, :2], ax2) is ax2
    assert [t.get_text() for t in ax2.texts] == ["0", "1", "2", "3"]
    with pytest.raises(ValueError):
        plotting.floor_plan(np.zeros(3))


def test_trajectories():
    t = np.linspace(0, 1, 20)
    truth = uw.Trajectory(t, np.column_stack([t, t, np.zeros_like(t)]), name="truth")
    trajs = {"raw": np.column_stack([t, t + 0.1]), "truth": truth, "EKF": truth.pos_m[:, :2] + 0.05}
    ax = plotting.trajectories(trajs, anchors=ANCHORS)
    assert isinstance(ax, Axes)
    lines = _lines(ax)
    assert len(lines) == 4                                   # anchors + 3 tracks
    by_label = {ln.get_label(): ln for ln in lines}
    assert to_hex(by_label["truth"].get_color()) == "#000000"
    assert to_hex(by_label["EKF"].get_color()) == plotting.COLORS["EKF"]
    assert by_label["raw"].get_linestyle() == "None"
    assert by_label["truth"].get_zorder() == max(ln.get_zorder() for ln in lines)
    assert _legend_texts(ax) == ["anchors", "raw", "truth", "EKF"]
    with pytest.raises(ValueError):
        plotting.trajectories({"LS": np.zeros(5)})


def test_error_cdf():
    rng = np.random.default_rng(0)
    errors = {"LS": rng.rayleigh(0.2, 200), "EKF": rng.rayleigh(0.1, 150)}
    _, ax0 = plt.subplots()
    ax = plotting.error_cdf(errors, ax=ax0)
    assert ax is ax0
    lines = _lines(ax)
    assert len(lines) == 2 + 2 * 2                          # 2 level lines + (curve, markers) per estimator
    texts = _legend_texts(ax)
    assert len(texts) == 2
    for (name, e), text in zip(errors.items(), texts):
        assert text.startswith(name)
        assert f"CEP50 {metrics.cep50(e):.3g} m" in text and f"CEP95 {metrics.cep95(e):.3g} m" in text
    markers = [ln for ln in lines if ln.get_marker() == "o"]
    assert len(markers) == 2
    np.testing.assert_allclose(markers[0].get_xdata(), [metrics.cep50(errors["LS"]), metrics.cep95(errors["LS"])])
    np.testing.assert_allclose(markers[0].get_ydata(), [0.5, 0.95])
    curve = [ln for ln in lines if ln.get_label().startswith("LS")][0]
    assert to_hex(curve.get_color()) == plotting.COLORS["LS"]
    assert curve.get_ydata()[-1] == 1.0 and len(curve.get_xdata()) == 201


def test_error_cdf_units_nan_and_series():
    e = np.array([0.1, 0.2, np.nan, 0.4])
    with pytest.raises(ValueError, match="NaN"):
        plotting.error_cdf({"LS": e})
    ax = plotting.error_cdf({"LS": e}, nan="omit", unit="cm", cep=(0.5,))
    (text,) = _legend_texts(ax)
    assert "CEP50 20 cm" in text and "1 of 4 missing" in text
    assert ax.get_xlabel() == "error (cm)"
    assert len(_lines(ax)) == 3
    series = metrics.ErrorSeries("PF", np.arange(3.0), np.array([0.1, 0.3, 0.2]))
    ax = plotting.error_cdf({"PF": series})
    assert _legend_texts(ax)[0].startswith("PF")
    with pytest.raises(ValueError):
        plotting.error_cdf({"LS": [0.1]}, unit="mm")

