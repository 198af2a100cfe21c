import matplotlib
import numpy as np
import pandas as pd

from uwbwb.experiments import motion_models as mm
from uwbwb.sim import walk

matplotlib.use("Agg")


def test_figures(office_runs):
    import matplotlib.pyplot as plt

    cal, test = office_runs
    curves = pd.DataFrame({"run": "x", "tag": "t", "model": np.repeat(["RW", "RF", "RJ"], 2),
                           "sigma": [0.1, 1.0] * 3, "cep95_m": [0.5, 0.4, 0.6, 0.5, 0.7, 0.6]})
    fig = mm.calibration_figure(curves, best={"RW": 1.0, "RF": 1.0, "RJ": 1.0}, paper=mm.PAPER_SIGMA["office"])
    assert len(fig.axes) == 3 and fig.axes[0].get_xscale() == "log"
    plt.close(fig)
    est = mm.estimate(test[1], 0.3, {"RW": 1.0, "RF": 1.0, "RJ": 1.0}, gate_prob=None)
    ax = mm.paths_figure(est, t_range_s=(0.0, 10.0))
    assert ax.get_title() == "office, tag2"
    ax = mm.cdf_figure(est)
    assert len(ax.get_legend().get_texts()) == 5 and "common to all" in ax.get_title()
    ax = mm.scenario_figure(walk.office(), truth=test[0].truth)
    assert "6 anchors" in ax.get_title()
    plt.close("all")


def test_ranging_summary_and_covariance_figure():
    import matplotlib.pyplot as plt

    cfg = walk.office(duration_s=10.0)
    rec, truth = walk.simulate_walk(cfg, rng=np.random.default_rng(2))
    runs = mm.tag_runs(rec, dim=2, z_m={"tag1": 1.8, "tag2": 1.3})
    table = mm.ranging_summary(runs, truth)
    assert table.loc[("office", "tag2"), "NLOS links (%)"] > table.loc[("office", "tag1"), "NLOS links (%)"]
    assert abs(table.loc[("office", "tag1"), "LOS error mean (cm)"]) < 2
    emp = np.diag([4e-3, 3e-3, 2e-3, 3e-3, 5e-3]) + 2e-3
    fig = mm.covariance_figure(emp, 0.9 * emp, list("BCDEF"), title="x")
    assert len(fig.axes) == 3
    plt.close(fig)
