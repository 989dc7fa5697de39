"""Volume scene after ingest: off-table segmentation, the train/test lift draws, metrics, the NumPy
MLP (against scikit-learn), the per-fold training loop and the algebraic friction baseline."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd
import pytest

from tactilepipe.papillarray import physics
from tactilepipe.papillarray import messages as pa
from tactilepipe.papillarray.bagio import write_bag
from tactilepipe.core.errors import InputError
from tactilepipe.core.metrics import mae, r2_score, rmse
from tactilepipe.papillarray.shards import ingest_bag
from tactilepipe.volume import baseline, simulate as vsim
from tactilepipe.volume.dataset import _longest_run, build_dataset, off_table_segment, read_shard
from tactilepipe.volume.folds import make_folds
from tactilepipe.volume.mlp import MLPConfig, MLPRegressor
from tactilepipe.volume.train import fit_modality

from support.volume_data import baseline_data

G = 9.81


# ================================ segmentation ==================================================

def _truth(rec: dict) -> tuple[int, int]:
    return _longest_run(rec["off_table"])


def _pose_tolerance(rec: dict, sim: dict, seg: dict) -> int:
    """Samples by which the pose segment may start late / stop early: the truth starts when the pad
    springs carry the weight (z ~ 0.2 mm), the pose method when z passes the threshold (2 mm). The
    minimum-jerk move needs t_thr to climb the threshold; add the pose period (the pose is linearly
    interpolated onto the sensor clock) and one sample of rounding."""
    lift_s = rec["phases"]["lift"][1] - rec["phases"]["lift"][0]
    t = np.linspace(0, lift_s, 100001)
    z, _ = physics.minimum_jerk(t, lift_s, sim["lift_height_m"])
    t_thr = t[np.argmax(z * 1000.0 > seg["pose_lift_threshold_mm"])]
    rate = sim["rate_hz"]
    return math.ceil(t_thr * rate) + math.ceil(rate / sim["pose_rate_hz"]) + 1


def _force_tolerance(sim: dict, seg: dict) -> int:
    """The force method smooths |Fy| over force_smooth_s: its edges may move by up to one window."""
    return math.ceil(seg["force_smooth_s"] * sim["rate_hz"])


def test_pose_segment_agrees_with_the_truth(sim_lifts, smoke_params):
    sim, seg = smoke_params["simulate_volume"], smoke_params["segment"]
    for item in sim_lifts:
        rec = item["rec"]
        shard = read_shard(item["shard"])
        assert len(shard["t"]) == len(rec["t"])               # sensor 0's clock is the simulator's
        t0, t1 = _truth(rec)
        start, stop, used = off_table_segment(shard, {**seg, "method": "auto"}, item["shard"])
        assert used == "pose"
        tol = _pose_tolerance(rec, sim, seg)
        assert tol < 0.3 * sim["rate_hz"]                       # a small part of a ~4 s off-table phase
        # the pose threshold (2 mm) is above the lift at which the load leaves the table, so the
        # segment sits inside the truth: every sample it keeps is really off the table
        assert 0 <= start - t0 <= tol, (start, t0, tol)
        assert 0 <= t1 - stop <= tol, (stop, t1, tol)
        assert rec["off_table"][start:stop].all()


@pytest.mark.parametrize("index", [1, 2])             # 150 ml and 300 ml
def test_force_segment_agrees_with_the_truth(sim_lifts, smoke_params, index):
    sim, seg = smoke_params["simulate_volume"], smoke_params["segment"]
    item = sim_lifts[index]
    rec = item["rec"]
    t0, t1 = _truth(rec)
    start, stop, used = off_table_segment(read_shard(item["shard"]), {**seg, "method": "force"})
    assert used == "force"
    tol = _force_tolerance(sim, seg)
    assert abs(start - t0) <= tol and abs(stop - t1) <= tol, (start, t0, stop, t1, tol)


def test_force_segment_of_a_light_container_at_100_hz(sim_lifts, smoke_params):
    sim, seg = smoke_params["simulate_volume"], smoke_params["segment"]
    item = sim_lifts[0]
    assert item["lift"].volume_ml == 0 and sim["rate_hz"] == 100
    t0, t1 = _truth(item["rec"])
    start, stop, _ = off_table_segment(read_shard(item["shard"]), {**seg, "method": "force"})
    tol = _force_tolerance(sim, seg)
    assert abs(start - t0) <= tol and abs(stop - t1) <= tol, (start, t0, stop, t1, tol)


def _lift_shard(tmp_path, smoke_params, volume, index=0, with_pose=True, **sim_changes):
    """Simulate one lift and ingest it; optionally leave the arm pose topic out of the bag."""
    sim = {**smoke_params["simulate_volume"], **sim_changes}
    lift = vsim.Lift(f"v{int(volume):03d}_main_l{index:02d}", volume, "main", 0, index)
    bag = tmp_path / f"{lift.name}.bag"
    if with_pose:
        rec = vsim.write_lift_bag(bag, lift, sim, smoke_params["seed"])
    else:
        rec = vsim.simulate_lift(lift, sim, smoke_params["seed"])
        stamps = vsim.lift_start_ns(lift, sim) + np.round(rec["t"] * 1e9).astype(np.int64)
        topics = {}
        for s in (0, 1):
            raws = pa.encode_sensor_states(stamps, stamps // 1000, rec["disp"][:, s], rec["force"][:, s],
                                           rec["in_contact"][:, s], np.zeros((len(stamps), 9), np.int32))
            topics[pa.sensor_topic(0, s)] = (pa.SENSOR_STATE, stamps.tolist(), raws)
        write_bag(bag, topics)
    shard = tmp_path / f"{lift.name}.parquet"
    ingest_bag(bag, shard)
    return rec, shard


def test_lift_that_never_leaves_the_table(tmp_path, smoke_params):
    # 0.1 mm of arm travel stretches the pads by only 2.2 N: a 356 g container stays on the table
    rec, shard = _lift_shard(tmp_path, smoke_params, 300.0, lift_height_m=1e-4)
    assert not rec["off_table"].any()
    with pytest.raises(InputError, match="never leaves the table.*pose method") as err:
        off_table_segment(read_shard(shard), smoke_params["segment"], shard)
    assert str(shard) in str(err.value)
    lifts = pd.DataFrame([{"lift": "s/x", "session": "s", "volume_ml": 300.0, "set": "main", "shard": str(shard)}])
    with pytest.raises(InputError, match="never leaves the table"):
        build_dataset(lifts, smoke_params["segment"], smoke_params["papillarray_axes"], smoke_params["volume_checks"])


def test_lift_without_load_never_leaves_the_table_by_force(tmp_path, smoke_params):
    rec, shard = _lift_shard(tmp_path, smoke_params, 150.0, lift_height_m=1e-7)
    assert not rec["off_table"].any()
    with pytest.raises(InputError, match="never leaves the table.*force method"):
        off_table_segment(read_shard(shard), {**smoke_params["segment"], "method": "force"}, shard)


def test_recording_without_pose(tmp_path, smoke_params):
    rec, shard = _lift_shard(tmp_path, smoke_params, 200.0, index=1, with_pose=False)
    data = read_shard(shard)
    assert data["tool_z"] is None
    with pytest.raises(InputError, match=r"segment.method is 'pose' but the bag has no /tool_pose topic") as err:
        off_table_segment(data, {**smoke_params["segment"], "method": "pose"}, shard)
    assert str(shard) in str(err.value)
    start, stop, used = off_table_segment(data, smoke_params["segment"], shard)     # auto falls back
    assert used == "force"
    t0, t1 = _truth(rec)
    tol = _force_tolerance(smoke_params["simulate_volume"], smoke_params["segment"])
    assert abs(start - t0) <= tol and abs(stop - t1) <= tol


def test_build_dataset_keeps_the_off_table_samples(sim_lifts, smoke_params):
    lifts = pd.DataFrame([{"lift": f"sim/{it['lift'].name}", "session": "sim", "volume_ml": it["lift"].volume_ml,
                           "set": "main", "shard": str(it["shard"])} for it in sim_lifts])
    data, qc = build_dataset(lifts, smoke_params["segment"], smoke_params["papillarray_axes"],
                             smoke_params["volume_checks"])
    assert list(data.columns) == ["lift", "session", "volume_ml", "set", "t", "fx0", "fy0", "fz0", "fx1", "fy1", "fz1"]
    assert list(qc["lift"]) == list(lifts["lift"])
    assert (qc["segment_method"] == "pose").all()
    for it, q in zip(sim_lifts, qc.itertuples()):
        part = data[data["lift"] == q.lift]
        assert len(part) == q.off_table_samples
        assert q.samples == len(it["rec"]["t"])
        assert (part["volume_ml"] == it["lift"].volume_ml).all()
        assert 3.0 < q.off_table_s < 5.0
        # every kept sample is off the table: sensor 0 carries about half the weight
        m = (56.0 + it["lift"].volume_ml) / 1000
        assert part["fy0"].mean() == pytest.approx(m * G / 2, abs=0.12)
        assert part["fz0"].mean() == pytest.approx(smoke_params["simulate_volume"]["grip_force_n"], rel=0.15)
    assert not data[["fx0", "fy0", "fz0", "fx1", "fy1", "fz1"]].isna().any().any()


def test_read_shard_errors(tmp_path, sensor_stream, write_ros1_bag):
    with pytest.raises(InputError, match="cannot read shard"):
        read_shard(tmp_path / "absent.parquet")
    s = sensor_stream(n=10)
    raws = pa.encode_sensor_states(s["stamp_ns"], s["tus"], s["disp"], s["force"], s["in_contact"], s["slip_state"])
    bag = write_ros1_bag(tmp_path / "s1.bag", {pa.sensor_topic(0, 1): (pa.SENSOR_STATE, s["stamp_ns"].tolist(), raws)})
    ingest_bag(bag, tmp_path / "s1.parquet")
    with pytest.raises(InputError, match="no /hub_0/sensor_0 messages"):
        read_shard(tmp_path / "s1.parquet")
    bag = write_ros1_bag(tmp_path / "s0.bag", {pa.sensor_topic(0, 0): (pa.SENSOR_STATE, s["stamp_ns"].tolist(), raws)})
    ingest_bag(bag, tmp_path / "s0.parquet")
    with pytest.raises(InputError, match=r"s0.parquet: shard has no /hub_0/sensor_1 messages: a lift is read on both"):
        read_shard(tmp_path / "s0.parquet")


def test_longest_run():
    assert _longest_run(np.array([], bool)) == (0, 0)
    assert _longest_run(np.array([0, 0, 0], bool)) == (0, 0)
    assert _longest_run(np.array([1, 1, 0, 1, 1, 1, 0, 1], bool)) == (3, 6)
    assert _longest_run(np.array([0, 1, 1, 1], bool)) == (1, 4)


# ================================ folds =========================================================

def _lift_table(counts: dict[float, int], unseen: dict[float, int] | None = None) -> pd.DataFrame:
    rows = [{"lift": f"s/v{int(v):03d}_main_l{i:02d}", "volume_ml": v, "set": "main"}
            for v, n in counts.items() for i in range(n)]
    rows += [{"lift": f"s/v{int(v):03d}_unseen_l{i:02d}", "volume_ml": v, "set": "unseen"}
             for v, n in (unseen or {}).items() for i in range(n)]
    return pd.DataFrame(rows)


def test_folds_are_stratified_disjoint_and_skip_unseen_lifts():
    volumes = [0.0, 50.0, 100.0, 150.0]
    lifts = _lift_table({v: 7 for v in volumes}, unseen={75.0: 3, 100.0: 2})
    folds = make_folds(lifts, n_folds=5, n_train=4, n_test=2, seed=3)
    assert [f["fold"] for f in folds] == list(range(5))
    main = set(lifts.loc[lifts["set"] == "main", "lift"])
    volume_of = dict(zip(lifts["lift"], lifts["volume_ml"]))
    for f in folds:
        assert not set(f["train"]) & set(f["test"])
        assert set(f["train"]) | set(f["test"]) <= main                  # unseen lifts never enter a fold
        assert len(set(f["train"])) == len(f["train"]) == 4 * len(volumes)
        for v in volumes:
            assert sum(volume_of[l] == v for l in f["train"]) == 4
            assert sum(volume_of[l] == v for l in f["test"]) == 2
    assert len({tuple(f["test"]) for f in folds}) > 1                     # draws differ between folds


def test_folds_are_deterministic_per_seed():
    lifts = _lift_table({v: 14 for v in (0.0, 100.0, 200.0)})
    a = make_folds(lifts, 3, 10, 4, seed=2026)
    assert a == make_folds(lifts.sample(frac=1.0, random_state=1), 3, 10, 4, seed=2026)   # row order irrelevant
    assert a != make_folds(lifts, 3, 10, 4, seed=2027)


def test_too_few_lifts_names_the_counts():
    lifts = _lift_table({0.0: 14, 50.0: 9, 100.0: 14, 150.0: 3}, unseen={75.0: 20})
    with pytest.raises(InputError, match=r"too few lifts for the folds \(50 ml has 9, 150 ml has 3; "
                                         r"each volume needs 14 = 10 train \+ 4 test\)") as err:
        make_folds(lifts, 5, 10, 4, seed=0, source="data/volume.parquet")
    assert str(err.value).startswith("data/volume.parquet: ")


def test_one_volume_is_not_enough():
    with pytest.raises(InputError, match="at least two volumes"):
        make_folds(_lift_table({100.0: 20}), 2, 5, 5, seed=0)


# ================================ metrics =======================================================

def test_metrics_hand_values():
    y, p = [1.0, 2.0, 3.0, 4.0], [1.0, 2.0, 3.0, 5.0]
    assert r2_score(y, p) == pytest.approx(1 - 1 / 5)          # ss_res 1, ss_tot 5
    assert mae(y, p) == pytest.approx(0.25)
    assert rmse(y, p) == pytest.approx(0.5)
    assert r2_score(y, y) == 1.0
    assert r2_score(y, [2.5] * 4) == pytest.approx(0.0)          # the mean predictor
    assert r2_score([0.0, 10.0], [10.0, 0.0]) == pytest.approx(-3.0)
    assert mae([0, 0, 0], [-1, 2, 3]) == pytest.approx(2.0)
    assert rmse([0, 0], [3, 4]) == pytest.approx(math.sqrt(12.5))


def test_r2_is_nan_for_constant_targets():
    assert math.isnan(r2_score([5.0, 5.0, 5.0], [5.0, 4.0, 6.0]))
    assert math.isnan(r2_score([5.0], [5.0]))


# ================================ MLP ===========================================================

def _volume_problem(lifts_per_volume: int, samples_per_lift: int, seed: int):
    """Synthetic off-table samples: Fy carries the weight (with per-lift and per-sample noise), Fz the
    grip (per-lift repeatability), Fx a little grasp tilt."""
    rng = np.random.default_rng(seed)
    xs, ys = [], []
    for v in np.repeat(np.arange(0.0, 301.0, 50.0), lifts_per_volume):
        grip = 6.0 * (1 + 0.04 * rng.standard_normal())
        fy = (56 + v) / 1000 * G / 2 * (1 + 0.01 * rng.standard_normal()) + 0.02 * rng.standard_normal(samples_per_lift)
        fz = grip + 0.05 * rng.standard_normal(samples_per_lift)
        fx = 0.02 * fy + 0.02 * rng.standard_normal(samples_per_lift)
        xs.append(np.c_[fx, fy, fz])
        ys.append(np.full(samples_per_lift, v))
    return np.vstack(xs), np.concatenate(ys)


def test_mlp_matches_sklearn(smoke_params):
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.neural_network import MLPRegressor as SkMLP
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    x_tr, y_tr = _volume_problem(10, 200, seed=0)       # 14k training samples
    x_te, y_te = _volume_problem(4, 200, seed=1)
    ours = MLPRegressor(MLPConfig(), seed=0).fit(x_tr, y_tr)
    r2_ours = r2_score(y_te, ours.predict(x_te))
    sk = make_pipeline(StandardScaler(), SkMLP(hidden_layer_sizes=(2,), alpha=1e-4, batch_size=200,
                                               learning_rate_init=1e-3, tol=1e-4, random_state=0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        sk.fit(x_tr, y_tr)
    r2_sk = r2_score(y_te, sk.predict(x_te))
    assert r2_sk > 0.99                                  # the problem is learnable by a 2-unit net
    assert abs(r2_ours - r2_sk) < 0.01, (r2_ours, r2_sk)
    assert ours.converged and ours.n_iter == len(ours.loss_curve) < 200


def _restart_problem():
    rng = np.random.default_rng(5)
    v = rng.choice(np.arange(0.0, 301.0, 50.0), 2000)
    x = np.c_[(56 + v) / 1000 * G / 2 + 0.03 * rng.standard_normal(2000), 6 + 0.2 * rng.standard_normal(2000)]
    return x, v


def test_restarts_never_end_worse_than_a_single_start():
    x, v = _restart_problem()
    worse = []
    for seed in (0, 1, 2, 9, 15, 19):
        one = MLPRegressor(MLPConfig(restarts=1, max_iter=60), seed=seed).fit(x, v)
        three = MLPRegressor(MLPConfig(restarts=3, max_iter=60), seed=seed).fit(x, v)
        if three.loss_curve[-1] > one.loss_curve[-1] + 1e-12:
            worse.append((seed, one.loss_curve[-1], three.loss_curve[-1]))
    assert worse == []


def test_mlp_is_deterministic_for_a_seed():
    x, v = _restart_problem()
    cfg = MLPConfig(max_iter=15)
    a = MLPRegressor(cfg, seed=4).fit(x, v)
    b = MLPRegressor(cfg, seed=4).fit(x, v)
    c = MLPRegressor(cfg, seed=5).fit(x, v)
    np.testing.assert_array_equal(a.predict(x), b.predict(x))
    assert a.loss_curve == b.loss_curve
    assert not np.array_equal(a.predict(x), c.predict(x))


@pytest.mark.parametrize("bad", ["nan_x", "inf_x", "nan_y", "shape", "empty"])
def test_mlp_rejects_bad_input(bad):
    x, y = np.ones((10, 2)), np.arange(10.0)
    if bad == "nan_x":
        x[3, 1] = np.nan
    elif bad == "inf_x":
        x[0, 0] = np.inf
    elif bad == "nan_y":
        y[5] = np.nan
    elif bad == "shape":
        y = y[:9]
    else:
        x, y = x[:0], y[:0]
    with pytest.raises(ValueError, match="NaN or inf" if bad.startswith(("nan", "inf")) else "fit needs"):
        MLPRegressor(MLPConfig(max_iter=2), seed=0).fit(x, y)


def test_mlp_config_from_params(smoke_params):
    cfg = MLPConfig.from_params(smoke_params["mlp"], restarts=1)
    assert cfg.max_iter == 60 and cfg.hidden_units == 2 and cfg.restarts == 1 and cfg.alpha == 1e-4


def test_fit_modality_predicts_test_and_unseen_lifts():
    rng = np.random.default_rng(0)
    rows = []
    volumes = [0.0, 100.0, 200.0, 300.0]
    for kind, vols, n in (("main", volumes, 4), ("unseen", [150.0], 2)):
        for v in vols:
            for i in range(n):
                fy = (56 + v) / 1000 * G / 2 + 0.01 * rng.standard_normal(50)
                rows.append(pd.DataFrame({"lift": f"{kind}{v:g}_{i}", "volume_ml": v, "set": kind, "fy0": fy,
                                          "fz0": 6 + 0.05 * rng.standard_normal(50)}))
    data = pd.concat(rows, ignore_index=True)
    folds = make_folds(data.drop_duplicates("lift"), 2, 3, 1, seed=1)
    preds, summary = fit_modality(data, folds, ["fy", "fz"], 0, MLPConfig(max_iter=100, learning_rate=0.01), seed=3)
    assert list(summary["fold"]) == [0, 1]
    assert (summary["r2"] > 0.95).all(), summary
    for f in folds:
        p = preds[preds["fold"] == f["fold"]]
        assert set(p.loc[p["set"] == "test", "lift"]) == set(f["test"])
        assert set(p.loc[p["set"] == "unseen", "lift"]) == {l for l in data["lift"].unique() if l.startswith("unseen")}
        assert len(p[p["set"] == "test"]) == data["lift"].isin(f["test"]).sum()
        assert summary.loc[f["fold"], "n_train"] == data["lift"].isin(f["train"]).sum()
    unseen = preds[preds["set"] == "unseen"]
    assert unseen["pred_ml"].mean() == pytest.approx(150.0, abs=15.0)


# ================================ baseline ======================================================

def test_estimate_volume_hand_value():
    # 1000 (1.0 + 0.25 * 6.0) / 9.81 - 56 = 2500 / 9.81 - 56
    assert baseline.estimate_volume(1.0, 6.0, 0.25, 9.81, 56.0) == pytest.approx(198.8420, abs=1e-3)
    np.testing.assert_allclose(baseline.estimate_volume([0.0, 0.054936], [0.0, 1.6481], 0.3, 9.81, 56.0),
                               [-56.0, 0.0], atol=1e-2)


def test_sweep_recovers_mu(smoke_params):
    p = smoke_params["baseline"]
    step = (p["mu_max"] - p["mu_min"]) / (p["n_mu"] - 1)
    mu_true = 0.2681
    data, folds = baseline_data(mu_true, p)
    res = baseline.sweep(data, folds, 0, p)
    assert abs(res["mu_star"] - mu_true) <= step
    assert (np.abs(res["optima"]["mu_opt"] - mu_true) <= step).all()
    assert not res["optima"]["on_edge"].any()
    assert (res["summary"]["r2"] > 0.999).all()
    assert (res["optima"]["r2_train"] > 0.999).all()
    assert len(res["curve"]) == len(folds) * p["n_mu"]
    # the mu-R² curve peaks at the optimum
    c0 = res["curve"][res["curve"]["fold"] == 0]
    assert c0["r2_train"].iloc[0] < res["optima"]["r2_train"].iloc[0]
    assert c0["r2_train"].iloc[-1] < res["optima"]["r2_train"].iloc[0]
    assert len(res["predictions"]) == sum(data["lift"].isin(f["test"]).sum() for f in folds)


def test_sweep_flags_an_optimum_on_the_edge(smoke_params):
    p = smoke_params["baseline"]
    data, folds = baseline_data(0.55, p)                     # true mu above the swept range
    res = baseline.sweep(data, folds, 0, p)
    assert res["optima"]["on_edge"].all()
    assert (res["optima"]["mu_opt"] == p["mu_max"]).all()
    data, folds = baseline_data(0.02, p)
    res = baseline.sweep(data, folds, 0, p)
    assert res["optima"]["on_edge"].all() and (res["optima"]["mu_opt"] == p["mu_min"]).all()


def test_a_pose_in_millimetres_is_refused(sim_lifts, smoke_params):
    item = sim_lifts[0]
    shard = read_shard(item["shard"])
    shard["tool_z"] = shard["tool_z"] * 1000.0                   # /tool_pose published in mm
    with pytest.raises(InputError, match=r"/tool_pose rises 100 above its rest height: more than an arm reaches "
                                         r"\(2 m\)\. The pose must be in metres"):
        off_table_segment(shard, {**smoke_params["segment"], "method": "auto"}, item["shard"])


@pytest.mark.parametrize("mu_s, mu_k, slides", [(0.6, 0.45, False), (0.12, 0.08, True)])
def test_a_grasp_that_slides_is_flagged_and_left_out(tmp_path, smoke_params, mu_s, mu_k, slides):
    from tactilepipe.papillarray.shards import ingest_bag
    from tactilepipe.volume import simulate as vsim
    from tactilepipe.volume.dataset import SLIP_HOLD_S, build_dataset
    sim = {**smoke_params["simulate_volume"], "friction_static": mu_s, "friction_kinetic": mu_k}
    lift = vsim.Lift("v300_main_l00", 300.0, "main", 0, 0)          # the heaviest container
    rec = vsim.write_lift_bag(tmp_path / "l.bag", lift, sim, smoke_params["seed"])
    ingest_bag(tmp_path / "l.bag", tmp_path / "l.parquet")
    assert "slip4" in pd.read_parquet(tmp_path / "l.parquet").columns          # the driver's flags, kept
    steady = {"lift": "s/steady", "session": "s", "volume_ml": 0.0, "set": "main",
              "shard": str(tmp_path / "steady.parquet")}
    vsim.write_lift_bag(tmp_path / "steady.bag", vsim.Lift("v000_main_l00", 0.0, "main", 0, 0),
                        smoke_params["simulate_volume"], smoke_params["seed"])
    ingest_bag(tmp_path / "steady.bag", tmp_path / "steady.parquet")
    lifts = pd.DataFrame([steady, {"lift": "s/heavy", "session": "s", "volume_ml": 300.0, "set": "main",
                                   "shard": str(tmp_path / "l.parquet")}])
    data, qc = build_dataset(lifts, smoke_params["segment"], smoke_params["papillarray_axes"],
                             smoke_params["volume_checks"])
    heavy = qc.set_index("lift").loc["s/heavy"]
    assert bool(heavy["slipped"]) is slides and bool(heavy["slip_s"] >= SLIP_HOLD_S) is slides
    assert ("s/heavy" in set(data["lift"])) is not slides
    assert not qc.set_index("lift").loc["s/steady", "slipped"]
    assert bool(rec["gross_slip"].any()) is slides                    # the simulator's own truth agrees


def test_a_label_heavier_than_what_the_pads_carry_is_refused(sim_lifts, smoke_params):
    item = sim_lifts[1]
    lifts = pd.DataFrame([{"lift": "s/x", "session": "s", "volume_ml": item["lift"].volume_ml, "set": "main",
                           "shard": str(item["shard"])}])
    build_dataset(lifts, smoke_params["segment"], smoke_params["papillarray_axes"],
                  smoke_params["volume_checks"])          # its own label: kept
    lifts["volume_ml"] = 5000.0                                                              # litres typed as ml
    with pytest.raises(InputError, match=r"lift s/x: lifts.csv gives 5000 ml \(49.05 N of water\) but the pads "
                                         r"carry \d\.\d\d N off the table"):
        build_dataset(lifts, smoke_params["segment"], smoke_params["papillarray_axes"], smoke_params["volume_checks"])
