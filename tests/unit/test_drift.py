"""Drift scene of study 001: simulator physics and determinism, fitting, naming errors, end to end."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from tactilepipe.core.config import load_params
from tactilepipe.drift import analyse, recordings, simulate
from tactilepipe.core.errors import InputError
from tactilepipe.papillarray.shards import ingest_bag

G = 9.81


@pytest.fixture(scope="module")
def smoke_params():
    return load_params(overrides={"scale": "smoke"})


@pytest.fixture(scope="module")
def smoke_session(tmp_path_factory, smoke_params):
    """A whole smoke-scale session: bags -> shards (ingested by the project's ingest_bag)."""
    root = tmp_path_factory.mktemp("drift_session")
    shards = []
    for name in simulate.session_plan(smoke_params):
        bag, shard = root / "raw" / f"{name}.bag", root / "shards" / f"{name}.parquet"
        simulate.write_drift_bag(bag, name, smoke_params)
        ingest_bag(bag, shard)
        shards.append(shard)
    simulate.write_session_meta(root / "raw", smoke_params)
    return root, shards


# --- simulator --------------------------------------------------------------------------------

def test_session_plan_names_every_recording(smoke_params):
    names = simulate.session_plan(smoke_params)
    times = ["00", "05", "10", "15", "20", "25", "30"]
    assert names == [f"unloaded_t{t}" for t in times] + [f"loaded_t{t}" for t in times]
    no_weight = {**smoke_params, "simulate_drift": {**smoke_params["simulate_drift"], "load_g": 0}}
    assert simulate.session_plan(no_weight) == [f"unloaded_t{t}" for t in times]


def test_same_seed_gives_byte_identical_bags(tmp_path, smoke_params):
    other_seed = {**smoke_params, "seed": smoke_params["seed"] + 1}
    simulate.write_drift_bag(tmp_path / "a" / "loaded_t05.bag", "loaded_t05", smoke_params)
    simulate.write_drift_bag(tmp_path / "b" / "loaded_t05.bag", "loaded_t05", smoke_params)
    simulate.write_drift_bag(tmp_path / "c" / "loaded_t05.bag", "loaded_t05", other_seed)
    first = (tmp_path / "a" / "loaded_t05.bag").read_bytes()
    assert first == (tmp_path / "b" / "loaded_t05.bag").read_bytes()
    assert first != (tmp_path / "c" / "loaded_t05.bag").read_bytes()
    assert list(tmp_path.glob("*/.*.tmp")) == []          # atomic write left no temporaries


def _measured_reading(rec: dict) -> tuple[float, float]:
    """(unloaded-part mean, loaded-part mean) of global Fz, parts found by the analysis."""
    fz = rec["force"][..., 2].astype(float).sum(axis=1)
    row = recordings.reading(rec["t"], fz, rec["run"], reference_n=0.0)
    return row["fz_unloaded_mean_n"], row["fz_loaded_mean_n"]


def test_simulated_drift_follows_the_configured_law(smoke_params):
    sim, sd = smoke_params["simulate_volume"], smoke_params["simulate_drift"]
    load_kg = sd["load_g"] / 1000.0
    end_s = sd["duration_min"] * 60.0
    # same law and numbers as the lift simulator; the ambient wobble (<= 0.01 N at each end) and
    # the noise of a ~400-sample mean (~0.003 N) bound the difference
    tol = 2 * simulate.AMBIENT_WOBBLE_N + 0.01
    # each mean is taken around the middle of its 5-s recording (+2.5 s)
    law_unloaded = simulate.thermal_drift_n(end_s + 2.5, 0.0, sim) - simulate.thermal_drift_n(2.5, 0.0, sim)
    law_loaded = (simulate.thermal_drift_n(end_s + 2.5, load_kg, sim)
                  - simulate.thermal_drift_n(2.5, load_kg, sim))

    u0 = _measured_reading(simulate.simulate_recording("unloaded_t00", smoke_params))
    u30 = _measured_reading(simulate.simulate_recording("unloaded_t30", smoke_params))
    l0 = _measured_reading(simulate.simulate_recording("loaded_t00", smoke_params))
    l30 = _measured_reading(simulate.simulate_recording("loaded_t30", smoke_params))

    assert u30[0] - u0[0] == pytest.approx(law_unloaded, abs=tol)
    assert l30[1] - l0[1] == pytest.approx(law_loaded, abs=tol)
    # the paper's magnitudes: ~0.3 N unloaded, ~0.5 N on the 500 g reading
    assert 0.25 < u30[0] - u0[0] < 0.35 and 0.45 < l30[1] - l0[1] < 0.55
    assert (l30[1] - l0[1]) - (u30[0] - u0[0]) > 0.1       # the weighed reading drifts more
    # load only changes the span: with the weight off the loaded run drifts like the unloaded one
    assert l30[0] - l0[0] == pytest.approx(law_unloaded, abs=tol)
    # the weight really reads as 500 g right after the bias (residual bias only)
    assert l0[1] - l0[0] == pytest.approx(load_kg * G, abs=0.02)


def test_loaded_recording_puts_weight_mostly_on_centre_pillar(smoke_params):
    rec = simulate.simulate_recording("loaded_t10", smoke_params)
    held = rec["load_n"] > 0.99 * rec["load_n"].max()
    fz = rec["force"][held, :, 2].mean(axis=0)
    assert np.argmax(fz) == 4
    assert not held[: int(0.4 * len(held) / 5)].any() and not held[-int(0.4 * len(held) / 5):].any()


# --- fitting ----------------------------------------------------------------------------------

def _series(run: str, t, y) -> pd.DataFrame:
    return pd.DataFrame({"run": run, "t_min": np.asarray(t, float), "drift_n": np.asarray(y, float)})


def test_fit_recovers_a_known_polynomial():
    t = np.arange(0, 31, 5.0)
    y = 0.01 + 0.02 * t - 0.0003 * t**2
    fits = analyse.fit_models(_series("unloaded", t, y), [1, 2, 3], tolerance_n=0.1)
    row = fits.table.set_index("model").loc["poly2"]
    assert row["r2"] > 0.999999 and row["loo_r2"] > 0.999999
    np.testing.assert_allclose(fits.models["unloaded"]["poly2"].coef, [0.01, 0.02, -0.0003], atol=1e-9)
    assert fits.table.set_index("model").loc["poly1", "r2"] < row["r2"]


@pytest.mark.parametrize("amplitude", [0.35, 0.575])
def test_recalibration_interval_on_a_saturating_exponential(amplitude):
    tau, tol = 15.0, 0.1
    t = np.arange(0, 31, 5.0)
    rng = np.random.default_rng(0)
    y = amplitude * (1 - np.exp(-t / tau)) + 0.002 * rng.standard_normal(len(t))
    fits = analyse.fit_models(_series("loaded", t, y), [1, 2, 3], tolerance_n=tol)
    exp_row = fits.table.set_index("model").loc[analyse.EXP_MODEL]
    assert exp_row["r2"] > 0.999 and exp_row["loo_r2"] > 0.99
    assert fits.models["loaded"][analyse.EXP_MODEL].coef[2] == pytest.approx(tau, rel=0.1)
    analytic = -tau * math.log(1 - tol / amplitude)
    exact = analyse.recalibration_interval(fits.models["loaded"][analyse.EXP_MODEL], 30.0, tol)
    assert exact == pytest.approx(analytic, abs=0.15)
    # whichever model wins by LOO, the interval it gives is close to the truth
    assert fits.recalibration_interval_min["loaded"] == pytest.approx(analytic, abs=0.4)
    assert fits.recalibration_beyond_observed["loaded"] is False


def test_small_drift_gives_no_interval_instead_of_extrapolating():
    t = np.arange(0, 31, 5.0)
    fits = analyse.fit_models(_series("unloaded", t, 0.05 * (1 - np.exp(-t / 10))), [1, 2], tolerance_n=0.1)
    assert fits.recalibration_interval_min["unloaded"] is None
    assert fits.recalibration_beyond_observed["unloaded"] is True


def test_cross_run_r2_scores_one_run_with_the_other_runs_fit():
    t = np.arange(0, 31, 5.0)
    series = pd.concat([_series("unloaded", t, 0.35 * (1 - np.exp(-t / 15))),
                        _series("loaded", t, 0.35 * (1 - np.exp(-t / 15)))])
    fits = analyse.fit_models(series, [2], tolerance_n=0.1)
    assert fits.cross_run_r2["unloaded->loaded"]["poly2"] == pytest.approx(
        fits.table.query("run == 'loaded' and model == 'poly2'")["r2"].iloc[0])
    doubled = pd.concat([_series("unloaded", t, 0.35 * (1 - np.exp(-t / 15))),
                         _series("loaded", t, 0.70 * (1 - np.exp(-t / 15)))])
    assert analyse.fit_models(doubled, [2], 0.1).cross_run_r2["unloaded->loaded"]["poly2"] < 0.5


# --- input errors -----------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["loaded-5min.parquet", "unloaded_t5.parquet", "heavy_t05.parquet",
                                  "loaded_t05.csv"])
def test_misnamed_file_raises_input_error_naming_it(tmp_path, name):
    good = tmp_path / "unloaded_t00.parquet"
    with pytest.raises(InputError) as err:
        recordings.drift_series([good, tmp_path / name], load_g=500)   # names are checked before any file is read
    assert name in str(err.value)


def test_unloaded_recording_with_a_weight_on_it_is_an_input_error(tmp_path):
    t = np.arange(500) / 100.0
    fz = np.where((t > 1) & (t < 4), 4.9, 0.0)
    paths = [tmp_path / f"unloaded_t{m:02d}.parquet" for m in (0, 5, 10)]
    for path in paths:
        pd.DataFrame({"stamp_ns": (t * 1e9).astype(np.int64), "sensor": 0,
                      "gfz": fz if "t05" in path.name else 0 * fz}).to_parquet(path)
    with pytest.raises(InputError, match="unloaded_t05.parquet.*something was on the sensor"):
        recordings.drift_series(paths, load_g=500)


def test_a_run_with_too_few_recordings_is_refused_stating_the_minimum(tmp_path):
    paths = [tmp_path / name for name in ("unloaded_t00.parquet", "loaded_t00.parquet", "unloaded_t05.parquet",
                                          "unloaded_t10.parquet")]
    with pytest.raises(InputError, match=r"run loaded has 1 recording\(s\) \(t = 0 min\): a drift curve needs at "
                                         r"least 3 per run"):
        recordings.drift_series(paths, load_g=500)               # counted from the names, before any file is read


# --- end to end -------------------------------------------------------------------------------

def test_end_to_end_smoke_session(tmp_path, smoke_session, smoke_params):
    root, shards = smoke_session
    out = tmp_path / "drift"
    metrics = analyse.run(shards, root / "raw" / "session.json", out, smoke_params)

    for rel in ["metrics/loaded.json", "metrics/unloaded.json", "scores.json", "drift_series.csv", "fits.csv",
                "fits.md", "figures/drift_curves.png"]:
        assert (out / rel).stat().st_size > 0, rel
    assert (out / "figures" / "drift_curves.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads((out / "scores.json").read_text()) == metrics and "fits" in metrics
    # DVC's metrics are the headline alone, a row per run: its drift in 30 min and recalibration interval
    for run in ("loaded", "unloaded"):
        assert json.loads((out / "metrics" / f"{run}.json").read_text()) == {
            k: metrics[k][run] for k in ("drift_30min_n", "recalibration_interval_min")}
    assert "| run | model |" in (out / "fits.md").read_text()
    page = (out / "fits.html").read_text()
    assert page.count("<table") == page.count("</table>") >= 2 and "<th>run</th>" in page and "|---|" not in page

    series = pd.read_csv(out / "drift_series.csv")
    assert len(series) == 14 and set(series["run"]) == {"unloaded", "loaded"}
    assert series.loc[series["run"] == "loaded", "n_loaded"].gt(0).all()

    runs = ["unloaded", "loaded"]
    assert all(math.isfinite(metrics["drift_30min_n"][r]) for r in runs)
    assert metrics["drift_30min_n"]["loaded"] > metrics["drift_30min_n"]["unloaded"] + 0.1
    for run in runs:
        scores = metrics["fits"][run]
        assert set(scores) == {"poly1", "poly2", "poly3", analyse.EXP_MODEL}
        assert all(math.isfinite(s["r2"]) and math.isfinite(s["loo_r2"]) for s in scores.values())
        assert metrics["best_model"][run] in scores
        minutes = metrics["recalibration_interval_min"][run]
        assert (minutes is None) == metrics["recalibration_beyond_observed"][run]
        assert minutes is None or 0 < minutes <= 30
    # the paper's finding: a fit describes its own run far better than the other run
    best_loaded = metrics["best_model"]["loaded"]
    assert (metrics["cross_run_r2"]["unloaded->loaded"][best_loaded]
            < metrics["fits"]["loaded"][best_loaded]["r2"] - 0.2)
    assert all(math.isfinite(v) for pair in metrics["cross_run_r2"].values() for v in pair.values())


# --- the session's own metadata ------------------------------------------------------------------

def test_reference_weight_comes_from_the_session_not_the_simulator(tmp_path, smoke_session, smoke_params):
    """A real session's weight is what its session.json says; simulator settings play no part."""
    root, shards = smoke_session
    assert json.loads((root / "raw" / "session.json").read_text()) == {
        "reference_load_g": smoke_params["simulate_drift"]["load_g"]}
    heavier = tmp_path / "session.json"
    heavier.write_text(json.dumps({"reference_load_g": smoke_params["simulate_drift"]["load_g"] + 100}))
    base = analyse.run(shards, root / "raw" / "session.json", tmp_path / "a", smoke_params)
    other = analyse.run(shards, heavier, tmp_path / "b", smoke_params)
    # 100 g more stated weight: the loaded reading's deviation drops by 0.981 N
    assert other["reference_n"]["loaded"] == pytest.approx(base["reference_n"]["loaded"] + 0.981, abs=1e-6)


@pytest.mark.parametrize("text, problem", [
    (None, "missing"), ("{", "not valid JSON"), ('{"reference_load_g": -1}', ">= 0"),
    ('{"reference_load_g": "500"}', ">= 0"), ('{"load": 500}', "reference_load_g"),
])
def test_bad_session_meta_is_an_input_error_naming_the_file(tmp_path, text, problem):
    from tactilepipe.drift import read_session_meta
    path = tmp_path / "session.json"
    if text is not None:
        path.write_text(text)
    with pytest.raises(InputError, match=f"session.json.*{problem}"):
        read_session_meta(path)


def test_a_recording_clipped_at_the_sensor_limit_is_refused(tmp_path):
    t = np.arange(800) / 100.0
    rng = np.random.default_rng(3)
    loaded = (t > 2) & (t < 6)
    frame = {"stamp_ns": (t * 1e9).astype(np.int64), "sensor": 0}
    for i in range(9):
        frame[f"fz{i}"] = rng.normal(0, 0.015, len(t)) + np.where(loaded, 0.6, 0.0)
    frame["fz4"] = np.minimum(frame["fz4"] + np.where(loaded, 9.0, 0.0), 8.0)       # the centre pillar at its limit
    frame["gfz"] = sum(frame[f"fz{i}"] for i in range(9))
    path = tmp_path / "loaded_t05.parquet"
    pd.DataFrame(frame).to_parquet(path)
    with pytest.raises(InputError, match=r"loaded_t05.parquet: pillar 4 of sensor 0 reads exactly 8.000 N in Z for "
                                         r"\d+ samples in a row: clipped at the sensor's measuring range"):
        recordings.recording_reading(path, "loaded", 4.9)
    frame["fz4"] = frame["fz4"] - np.where(loaded, 1.0, 0.0) * rng.uniform(0.1, 0.2, len(t))   # below the limit
    frame["gfz"] = sum(frame[f"fz{i}"] for i in range(9))
    pd.DataFrame(frame).to_parquet(path)
    assert recordings.recording_reading(path, "loaded", 4.9)["n_loaded"] > 200


def test_a_session_without_a_run_has_a_metric_row_of_nulls_for_it():
    """DVC declares every run's row; a drift session that recorded only one run still has both,
    the missing one empty (None in JSON), not a row copied from the other."""
    scores = {"drift_30min_n": {"unloaded": 0.31}, "recalibration_interval_min": {"unloaded": 4.8}}
    assert analyse.headline(scores) == {
        "unloaded": {"drift_30min_n": 0.31, "recalibration_interval_min": 4.8},
        "loaded": {"drift_30min_n": None, "recalibration_interval_min": None}}

