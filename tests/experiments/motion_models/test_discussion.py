import pandas as pd

from uwbwb.experiments import motion_models as mm


# --------------------------------------------------------------------------- discussion text

def _cep_table(rows: dict) -> pd.DataFrame:
    """(run, tag) → (raw, LS, RW, RF, RJ) CEP95 in metres, as :meth:`mm.Study.table` lays it out."""
    return pd.DataFrame([{"run": k[0], "tag": k[1], **dict(zip(["raw", "LS", "EKF-RW", "EKF-RF", "EKF-RJ"], v))}
                         for k, v in rows.items()]).set_index(["run", "tag"])


def _curves(cep_at_one: dict) -> pd.DataFrame:
    """Calibration curves whose mean is ``cep_at_one[model]`` at σ = 1 and 0.1 m higher at σ = 0.1 and 10."""
    return pd.DataFrame([{"run": "cal", "tag": "tag1", "model": m, "sigma": s,
                          "cep95_m": v + (0.0 if s == 1.0 else 0.1)}
                         for m, v in cep_at_one.items() for s in (0.1, 1.0, 10.0)])


SYNTHETIC = _cep_table({("office", "tag1"): (0.58, 0.45, 0.41, 0.40, 0.41),
                        ("office", "tag2"): (0.76, 0.59, 0.41, 0.49, 0.51),
                        ("agv1", "tag1"): (0.70, 0.48, 0.45, 0.44, 0.45),
                        ("agv1", "tag2"): (0.77, 0.52, 0.47, 0.48, 0.48),
                        ("agv2", "tag1"): (0.70, 0.55, 0.49, 0.53, 0.54),
                        ("agv2", "tag2"): (0.78, 0.64, 0.58, 0.61, 0.61)})


def test_discussion_reads_the_tables():
    ablation = pd.DataFrame({"EKF-RW": [0.412, 0.428], "EKF-RF": [0.492, 0.430], "EKF-RJ": [0.510, 0.429]})
    lias = {"calibrated ranges": _cep_table({("fast", "t0"): (0.103, 0.109, 0.091, 0.101, 0.101),
                                             ("fast", "t1"): (0.085, 0.089, 0.089, 0.088, 0.085)}),
            "raw ranges": _cep_table({("fast", "t0"): (0.281, 0.160, 0.137, 0.155, 0.155),
                                      ("fast", "t1"): (0.223, 0.143, 0.155, 0.148, 0.144)})}
    text = mm.discussion_markdown(SYNTHETIC, ablation=ablation,
                                  curves={"office": _curves({"RW": 0.40, "RF": 0.45, "RJ": 0.46}),
                                          "agv": _curves({"RW": 0.45, "RF": 0.47, "RJ": 0.50})},
                                  best={"office": {"RW": 1.6, "RF": 4.5, "RJ": 15.0},
                                        "agv": {"RW": 1.6, "RF": 4.5, "RJ": 0.5}},
                                  lias=lias, lias_label="lias-planar-uwb/fast")
    assert "RW 0.41/0.48 m against RF 0.77/1.13 m and RJ 1.03/1.14 m" in text           # the thesis, quoted
    assert "ranking holds, but only for the body-shadowed tag" in text
    assert "unshadowed tag (tag1) the three models are within 1.0 cm (RF ahead)" in text
    assert "body-shadowed tag (tag2) the random walk is 0.08 m better than the next model (RF)" in text
    assert "(0.08 m) shrinks to 0.00 m" in text
    # a simulator result supports a hypothesis about the thesis; it is not a finding about its data
    assert "supports a *hypothesis*" in text and "not a finding about the thesis' data" in text
    assert "0.30 m bias are assumptions built into our simulator" in text
    assert "So the thesis' ranking is reproduced" not in text
    assert "RW is usually best (3 of 4 tag-runs)" in text and "from −1.0 cm to 4.0 cm" in text
    assert "is not reproduced" in text and "factor of at most 1.24" in text and "up to 2.54" in text
    assert "they are 2.0 cm to 6.0 cm worse than the best random walk" in text
    # the random-walk σ equals the simulated speed by construction: stated, never compared
    assert "(1.6 m/s office, 1.6 m/s AGV) is not compared with the thesis'" in text
    assert "kind 'target'" in text and "factor of two" not in text
    assert "RF prefers larger values" in text and "RJ prefers other values" in text
    assert "Real data: no ranking" in text and "the winner changes from tag to tag (RJ, RW)" in text
    assert "improve only a little on LS (11 % lower CEP95 on average, at most 17 %)" in text
    assert "TDoA LS beats range multilateration (0.15 m against 0.25 m" in text
    assert "because" not in text.split("TDoA vs raw ranges")[1].split("\n")[0]     # no uncomputed mechanism
    assert "slowly varying bias" not in text
    assert "range multilateration is as good or better (0.09 m against 0.10 m)" in text
    assert "worse than LS, as in the thesis, but by less (+15 cm on average; thesis +61 cm)" in text
    assert "within 0.18 m of the random-walk EKF" in text and "6 well-spread anchors, 5 cm LOS noise" in text


def test_discussion_follows_other_outcomes():
    worse_rw = SYNTHETIC.copy()
    worse_rw["EKF-RW"] += 0.2                                                 # RW now last everywhere
    ablation = pd.DataFrame({"EKF-RW": [0.61, 0.60], "EKF-RF": [0.49, 0.43], "EKF-RJ": [0.51, 0.43]})
    iasl = _cep_table({("scenario2", "tag"): (0.30, 0.30, 0.20, 0.25, 0.26)})
    text = mm.discussion_markdown(worse_rw, ablation=ablation,
                                  curves={"office": _curves({"RW": 0.40, "RF": 0.38, "RJ": 0.45})},
                                  best={"office": {"RW": 0.1, "RF": 1.0, "RJ": 0.5}}, iasl=iasl,
                                  iasl_label="iasl-uwb-imu/scenario2")
    assert "the ranking does not hold" in text and "does not single out body shadowing" in text
    assert "RW is best on only 0 of 4 tag-runs" in text and "never lose to the random walk" in text
    assert "they are from 2.0 cm better to 5.0 cm worse than the best random walk" in text
    assert "RF prefers the same values as" in text
    assert "RJ prefers smaller values" in text
    assert "Real data: small differences" in text and "RW is best;" not in text and "RW is best." in text
    assert "The best filter improves on LS (33 % lower CEP95 on average" in text
    assert "TDoA vs raw ranges" not in text                                   # no LIAS variants
    nothing = mm.discussion_markdown(SYNTHETIC, curves={}, best={})
    assert "Neither real dataset was found" in nothing and "ablation" not in nothing


def _nis(verdicts: dict) -> pd.DataFrame:
    rows = [{"run/tag": k, "model": m, "verdict": v, "mean_nis_over_dof": x, "mean_lo": 0.95, "mean_hi": 1.05}
            for (k, m), (v, x) in verdicts.items()]
    return pd.DataFrame(rows).set_index(["run/tag", "model"])


def test_discussion_states_coverage_and_consistency():
    cov = pd.DataFrame({"LS": [97.0, 99.5], "common": [96.5, 99.0]},
                       index=pd.MultiIndex.from_tuples([("office", "tag1"), ("office", "tag2")]))
    nis = _nis({("office/tag1", "RW"): ("under-confident", 0.6), ("office/tag1", "RF"): ("consistent", 1.0),
                ("office/tag2", "RW"): ("over-confident", 1.4), ("office/tag2", "RF"): ("under-confident", 0.52)})
    text = mm.discussion_markdown(SYNTHETIC, curves={}, best={}, coverage=cov, nis=nis)
    assert "all five estimators have a position (96.5–99.0 % of the synthetic test epochs)" in text
    assert "LS has a fix on 97.0–99.5 % of them" in text and "changes no number" not in text
    full = pd.DataFrame({"LS": [100.0], "common": [100.0]}, index=pd.MultiIndex.from_tuples([("office", "tag1")]))
    assert "(100.0 % of the synthetic test epochs)" in mm.discussion_markdown(SYNTHETIC, curves={}, best={},
                                                                            coverage=full)
    assert "changes no number" in mm.discussion_markdown(SYNTHETIC, curves={}, best={}, coverage=full)
    assert "Consistency: the filters are not consistent" in text
    assert "Of 4 filter runs, 1 consistent, 1 over-confident, 2 under-confident" in text
    assert "Over-confident runs (EKF-RW)" in text and "mean NIS per degree of freedom of 0.52–0.60" in text
    ok = mm.discussion_markdown(SYNTHETIC, curves={}, best={},
                                nis=_nis({("office/tag1", "RW"): ("consistent", 1.01)}))
    assert "Consistency: the filters are consistent" in ok and "Over-confident" not in ok
    assert "Coverage" not in ok
