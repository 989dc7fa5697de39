"""Numerical stability on stiff and extreme cases.

Simulators: the pillar-creep integrators (stiff relaxation far below the sample period), very
stiff pillars and gels, heavy loads, forces beyond the sensors' range (pillar travel, Nano17 ADC
rails, gel depth), mu at the slip limit, zero force for a whole trial.
Learning and metrics: undefined R² (constant labels, one class), labels over 1e-3..1e3, NaN/inf
reaching a loss, a mu optimum on the edge of the sweep, skewed force distributions.
"""

from __future__ import annotations

import copy
import json
import math
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from support import tool_sim
from tactilepipe.papillarray import physics
from tactilepipe.core.errors import ConfigError, InputError, TactilepipeError
from tactilepipe.core.metrics import (R2_CONSTANT, R2_EMPTY, R2_NONFINITE, format_metric, r2_detail,
                                 r2_score)
from tactilepipe.core.tables import write_table
from tactilepipe.volume import baseline
from tactilepipe.volume import simulate as vsim
from tactilepipe.papillarray import viscoelastic as ve
from tactilepipe.volume.folds import make_folds
from tactilepipe.volume.mlp import MLPConfig, MLPDivergedError, MLPRegressor

from support.volume_data import baseline_data
from support.project import REPO

G = physics.G
SILICONE = ve.Prony((0.05, 0.05), (0.0005, 1.5))      # the benchmark's soft silicone: stiff at 100-1000 Hz


@pytest.fixture
def quiet(smoke_params) -> dict:
    """Smoke rig without measurement errors (exact physics), creep off."""
    return {**smoke_params["simulate_volume"], "noise_std_n": 0.0, "bias_residual_std_n": 0.0,
            "drift_inf_n": 0.0, "drift_per_kg_n": 0.0, "grip_force_rel_std": 0.0,
            "creep_fractions": [], "creep_tau_s": []}


def _lift(volume: float, index: int = 0) -> vsim.Lift:
    return vsim.Lift(f"v{int(volume):03d}_main_l{index:02d}", volume, "main", 0, index)


def _hold(rec: dict) -> np.ndarray:
    t0, t1 = rec["phases"]["hold"]
    return (rec["t"] >= t0) & (rec["t"] < t1)


# ================================ creep integrators (stiff ODE) =================================

def step_response(t: np.ndarray, prony: ve.Prony) -> np.ndarray:
    """Exact reading for a unit force step at t = 0 (modal solution)."""
    a, b = prony.system()
    g = np.asarray(prony.fractions, float)
    lam, vec = np.linalg.eig(a)
    # s(t) = -A^-1 b + V e^{lam t} V^-1 (A^-1 b)   with s(0) = 0
    s_inf = -np.linalg.solve(a, b)
    coef = np.linalg.solve(vec, -s_inf)
    s = s_inf[None, :] + np.real((vec[None, :, :] * (coef * np.exp(np.outer(t, lam)))[:, None, :]).sum(-1))
    return prony.g_inf + s @ g


def test_exponential_integrator_matches_the_analytic_step_response():
    t = np.arange(3000) * 0.002
    exact = step_response(t, SILICONE)
    assert exact[0] == pytest.approx(SILICONE.g_inf)                 # reads g_inf of a step at once
    assert exact[-1] == pytest.approx(1.0, abs=2e-3)                 # and creeps to the full load
    for sub in (1, 4):
        np.testing.assert_allclose(ve.integrate(np.ones(len(t)), 0.002, SILICONE, "exponential", sub),
                                   exact, atol=1e-12)


def test_stable_methods_converge_and_explicit_ones_are_refused_beyond_their_limit():
    t = np.arange(1500) * 0.002
    exact = step_response(t, SILICONE)
    err = {k: np.abs(ve.integrate(np.ones(len(t)), 0.002, SILICONE, "implicit_euler", k) - exact).max()
           for k in (1, 2, 4, 8)}
    assert err[8] < err[4] < err[2] < err[1] < 0.02                  # first order, converging
    assert err[1] / err[8] > 4
    # a 0.5-ms mode at 500 Hz: forward Euler and RK4 blow up with one step per sample ...
    for method in ("euler", "rk4"):
        blown = ve.integrate(np.ones(len(t)), 0.002, SILICONE, method, 1, check_stability=False)
        assert not np.isfinite(blown).all() or np.abs(blown).max() > 1e6
        with pytest.raises(ConfigError, match=rf"'{method}' is unstable at a step of 2 ms.*creep_substeps >= 2"):
            ve.integrate(np.ones(10), 0.002, SILICONE, method, 1)
        # ... and are fine within it
        ok = ve.integrate(np.ones(len(t)), 0.002, SILICONE, method, 2)
        assert np.abs(ok - exact).max() < 0.05
    assert ve.stability_limit_s(SILICONE, "euler") == pytest.approx(2 * 0.0005 / 0.95, rel=1e-3)


@pytest.mark.parametrize("method", ["exponential", "implicit_euler"])
def test_extremely_stiff_creep_stays_bounded(method):
    """Relaxation 1e-9 s at 100 Hz (h |lambda| ~ 1e7): the stable methods stay within the load."""
    stiff = ve.Prony((0.3, 0.2), (1e-9, 1e4))
    rng = np.random.default_rng(0)
    load = np.abs(np.cumsum(rng.standard_normal((400, 6)), axis=0))
    out = ve.integrate(load, 0.01, stiff, method, 1)
    assert np.isfinite(out).all()
    assert (out <= load.max() + 1e-9).all() and (out >= -1e-9).all()


def test_creep_parameters_are_checked():
    with pytest.raises(ConfigError, match="same length"):
        ve.Prony.from_params({"creep_fractions": [0.1], "creep_tau_s": []})
    with pytest.raises(ConfigError, match="sum to less than 1"):
        ve.Prony.from_params({"creep_fractions": [0.6, 0.5], "creep_tau_s": [1.0, 2.0]})
    assert not ve.Prony.from_params({"creep_fractions": [], "creep_tau_s": []}).active


def test_lift_with_creep_lags_the_load_and_settles(quiet):
    load = np.tile(np.linspace(0.0, 1.0, 50)[:, None], (1, 3))
    assert (ve.integrate_params(load, 0.01, quiet) == load).all()      # creep off: reading = load
    creepy = {**quiet, "creep_fractions": [0.05, 0.05], "creep_tau_s": [0.0005, 1.5]}
    rec = vsim.simulate_lift(_lift(300.0), creepy, 3)
    fz = rec["force"][..., 2].astype(np.float64).sum(axis=2)           # (T, sensor) read
    true = rec["true_force"][..., 2].sum(axis=2)
    assert np.isfinite(rec["force"]).all()
    close_end = np.searchsorted(rec["t"], rec["phases"]["close"][1])
    assert (fz[close_end] < true[close_end]).all()                      # lags the grip ramp
    hold = np.flatnonzero(_hold(rec))
    lag = true[hold] - fz[hold]                                          # (hold samples, sensor)
    assert (lag > 0).all() and lag.max() < 0.02 * quiet["grip_force_n"]   # < 2 % behind by the hold
    assert (lag[-1] < 0.6 * lag[0]).all()                                # and creeping towards it


def test_integrator_benchmark_table(tmp_path):
    # the benchmark script itself, at its quick setting: 500 Hz, substeps 1, 2 and 8
    proc = subprocess.run([sys.executable, str(REPO / "benchmarks" / "bench_integrators.py"), "--quick",
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    table = pd.read_csv(tmp_path / "integrators.csv")
    assert len(table) == len(ve.METHODS) * 3
    row = table.set_index(["method", "substeps"])
    assert row.loc[("exponential", 1), "integration_error_n"] < 1e-12
    assert row.loc[("exponential", 1), "max_error_n"] < 1e-3             # only the load's sampling
    for method in ("euler", "rk4"):
        assert row.loc[(method, 1), "diverged"] and not row.loc[(method, 1), "within_stability_limit"]
        assert not row.loc[(method, 2), "diverged"]
    assert not table[table["method"].isin(["exponential", "implicit_euler"])]["diverged"].any()
    assert (table["loop_ms"] > 0).all() and (table["modal_ms"] > 0).all()
    # the Python reference loop and the simulator's modal recursion give the same reading
    assert (table.loc[~table["diverged"], "loop_vs_modal_n"] < 1e-9).all()
    assert "| inf |" in (tmp_path / "integrators.md").read_text()
    assert (tmp_path / "integrators.png").stat().st_size > 0


# ================================ stiff pillars, heavy loads, range ==============================

@pytest.mark.parametrize("k", [4.0, 1e3, 1e6])
def test_normal_load_map_of_very_stiff_pillars_sums_to_the_grip(k, vsim_params):
    offsets = physics.pillar_offsets_mm(vsim_params["pillar_height_steps_mm"])
    grip = np.array([0.0, 1e-3, 6.0, 600.0])
    fz = physics.normal_load_map(grip, offsets, np.array([0.01, -0.004]), vsim_params["pillar_pitch_mm"], k)
    assert np.isfinite(fz).all() and (fz >= 0).all()
    np.testing.assert_allclose(fz.sum(axis=1), grip, rtol=1e-9, atol=1e-10)    # N


def test_very_stiff_pillars_carry_the_load_exactly(quiet):
    stiff = {**quiet, "pillar_normal_stiffness_n_per_mm": 1e4, "pillar_tangential_stiffness_n_per_mm": 1e4}
    rec = vsim.simulate_lift(_lift(300.0), stiff, 1)
    f = rec["force"].astype(np.float64)
    assert np.isfinite(f).all() and rec["saturated_samples"] == 0
    hold = _hold(rec)
    np.testing.assert_allclose(f[hold][..., 2].sum(axis=2), quiet["grip_force_n"], rtol=1e-5)
    shear = np.hypot(f[hold][..., 0].sum(axis=2), f[hold][..., 1].sum(axis=2)).sum(axis=1)
    np.testing.assert_allclose(shear, (quiet["container_mass_g"] + 300) / 1000 * G, rtol=1e-4)


def test_heavy_load_slides_at_the_kinetic_limit_without_nan(quiet):
    """5 litres in the 6-N grip: the pads cannot hold it - gross slip, shear capped at mu_k N."""
    rec = vsim.simulate_lift(_lift(5000.0), quiet, 2)
    hold = _hold(rec)
    assert np.isfinite(rec["force"]).all()
    assert rec["gross_slip"][hold].all()
    f = rec["force"][hold].astype(np.float64)
    shear = np.hypot(f[..., 0].sum(axis=2), f[..., 1].sum(axis=2))
    np.testing.assert_allclose(shear, quiet["friction_kinetic"] * quiet["grip_force_n"], rtol=1e-5)


def test_forces_beyond_the_pillar_range_saturate_and_are_counted(quiet, tmp_path):
    from tactilepipe.papillarray.shards import ingest_bag
    strong = {**quiet, "grip_force_n": 60.0}                 # centre pillar ~ 20 N > 2 mm x 4 N/mm
    rec = vsim.write_lift_bag(tmp_path / "strong.bag", _lift(300.0), strong, 4)
    limit = strong["pillar_travel_mm"] * strong["pillar_normal_stiffness_n_per_mm"]
    fz = rec["force"][..., 2]
    assert np.isfinite(rec["force"]).all()
    assert rec["saturated_samples"] > 0 and rec["saturated"].sum() > 0
    assert fz.max() == pytest.approx(limit) and (np.abs(fz) <= limit + 1e-6).all()
    assert (rec["true_force"][..., 2].max() > limit)          # the truth was beyond it
    np.testing.assert_allclose(fz[rec["saturated"][..., 2]], limit, rtol=1e-6)   # clipped to the edge
    # the real sensor's saturated readings go through ingest like any other (no NaN, no error)
    ingest_bag(tmp_path / "strong.bag", tmp_path / "strong.parquet")
    shard = pd.read_parquet(tmp_path / "strong.parquet")
    assert np.isfinite(shard["gfz"].dropna()).all()
    assert shard["gfz"].max() <= 9 * limit + 1e-3
    normal = vsim.simulate_lift(_lift(300.0), quiet, 4)
    assert normal["saturated_samples"] == 0                  # the default rig stays in range


def test_drift_recordings_count_saturation(smoke_params):
    from tactilepipe.drift import simulate as dsim
    p = copy.deepcopy(smoke_params)
    assert dsim.simulate_recording("loaded_t00", p)["saturated_samples"] == 0
    p["simulate_drift"]["load_g"] = 10000.0                  # 98 N on 9 pillars: beyond 8 N each
    rec = dsim.simulate_recording("loaded_t00", p)
    assert rec["saturated_samples"] > 0 and np.isfinite(rec["force"]).all()
    assert rec["force"][..., 2].max() == pytest.approx(2.0 * 4.0)


# ================================ mu at the slip limit ===========================================

@pytest.fixture
def pad_fz(vsim_params) -> np.ndarray:
    offsets = physics.pillar_offsets_mm(vsim_params["pillar_height_steps_mm"])
    return physics.normal_load_map(np.array([6.0]), offsets, np.zeros(2), vsim_params["pillar_pitch_mm"],
                                vsim_params["pillar_normal_stiffness_n_per_mm"])[0]


@pytest.mark.parametrize("mu_s,mu_k", [(0.6, 0.45), (0.5, 0.5)])
def test_demand_at_exactly_the_static_limit(pad_fz, mu_s, mu_k):
    cap = mu_s * pad_fz.sum()
    demand = np.zeros((4, 2))
    demand[:, 1] = [0.5 * cap, cap * (1 - 1e-12), cap, cap * (1 + 1e-9)]
    forces, slipping, gross = vsim.tangential_forces(demand, np.tile(pad_fz, (4, 1)), 1.2, mu_s, mu_k)
    assert np.isfinite(forces).all()
    total = np.linalg.norm(forces.sum(axis=1), axis=1)
    mag = np.linalg.norm(forces, axis=2)
    contact = pad_fz > 0
    assert (mag[:, contact] <= mu_s * pad_fz[contact] * (1 + 1e-9)).all()     # never beyond mu_s N
    assert not gross[0] and total[0] == pytest.approx(demand[0, 1], rel=1e-12)
    # beyond the static limit the pad carries at most its kinetic capacity (equal to it when mu_s = mu_k)
    assert total[-1] <= mu_k * pad_fz.sum() * (1 + 1e-9) + 1e-12
    assert total[-1] == pytest.approx(mu_k * pad_fz.sum() if gross[-1] else demand[-1, 1], rel=1e-9)


def test_lift_at_the_slip_limit(quiet):
    """Friction set so the heaviest lift's peak load (m (g + a) / 2 per pad) sits at mu_s N."""
    mass = (quiet["container_mass_g"] + 300.0) / 1000.0
    mu = mass * G / 2 / quiet["grip_force_n"]
    at_limit = {**quiet, "friction_static": mu, "friction_kinetic": mu}
    rec = vsim.simulate_lift(_lift(300.0), at_limit, 6)
    assert np.isfinite(rec["force"]).all()
    f = rec["force"][_hold(rec)].astype(np.float64)
    shear = np.hypot(f[..., 0].sum(axis=2), f[..., 1].sum(axis=2))
    assert (shear <= mu * quiet["grip_force_n"] * (1 + 1e-5)).all()


# ================================ zero force for a whole trial ===================================

def test_zero_force_lift_is_refused_by_force_segmentation(quiet, smoke_params, tmp_path):
    from tactilepipe.papillarray.shards import ingest_bag
    from tactilepipe.volume import dataset
    empty = {**smoke_params["simulate_volume"], "grip_force_n": 0.0}       # nothing grasped
    rec = vsim.write_lift_bag(tmp_path / "empty.bag", _lift(100.0), empty, 1)
    assert np.isfinite(rec["force"]).all() and np.abs(rec["force"]).max() < 0.2   # noise only
    ingest_bag(tmp_path / "empty.bag", tmp_path / "empty.parquet")
    lifts = pd.DataFrame([{"lift": "s/empty", "session": "s", "volume_ml": 100.0, "set": "main",
                           "shard": str(tmp_path / "empty.parquet")}])
    with pytest.raises(InputError, match="never leaves the table"):
        dataset.build_dataset(lifts, {**smoke_params["segment"], "method": "force"}, smoke_params["papillarray_axes"],
                              smoke_params["volume_checks"])


def test_zero_force_lift_is_not_silently_kept_by_pose_segmentation(smoke_params, tmp_path):
    from tactilepipe.papillarray.shards import ingest_bag
    from tactilepipe.volume import dataset
    empty = {**smoke_params["simulate_volume"], "grip_force_n": 0.0}
    vsim.write_lift_bag(tmp_path / "empty.bag", _lift(100.0), empty, 1)
    ingest_bag(tmp_path / "empty.bag", tmp_path / "empty.parquet")
    lifts = pd.DataFrame([{"lift": "s/empty", "session": "s", "volume_ml": 100.0, "set": "main",
                           "shard": str(tmp_path / "empty.parquet")}])
    try:
        data, qc = dataset.build_dataset(lifts, smoke_params["segment"], smoke_params["papillarray_axes"],
                                         smoke_params["volume_checks"])
    except InputError:
        return                                            # refused with a message: fine
    assert "dropped" in qc.columns and qc["dropped"].sum() == 1


def test_pose_segmentation_names_the_missing_load(smoke_params, tmp_path):
    from tactilepipe.papillarray.shards import ingest_bag
    from tactilepipe.volume import dataset
    empty = {**smoke_params["simulate_volume"], "grip_force_n": 0.0}
    vsim.write_lift_bag(tmp_path / "empty.bag", _lift(100.0), empty, 1)
    ingest_bag(tmp_path / "empty.bag", tmp_path / "empty.parquet")
    rec = dataset.read_shard(tmp_path / "empty.parquet")
    assert rec["tool_z"] is not None                          # the arm did rise
    with pytest.raises(InputError, match=r"empty\.parquet: the pads carry no load off the table .* "
                                         r"by the pose method, need 10 x the rest noise"):
        dataset.off_table_segment(rec, smoke_params["segment"], tmp_path / "empty.parquet")
    # an empty container (0 ml: only its own 56 g) is a load, and is kept
    vsim.write_lift_bag(tmp_path / "light.bag", _lift(0.0), smoke_params["simulate_volume"], 1)
    ingest_bag(tmp_path / "light.bag", tmp_path / "light.parquet")
    light = dataset.read_shard(tmp_path / "light.parquet")
    assert dataset.off_table_segment(light, smoke_params["segment"], "light")[2] == "pose"


def test_zero_force_drift_recordings(smoke_params):
    from tactilepipe.drift import recordings
    t = np.arange(500) / 100.0
    zero = np.zeros_like(t)
    row = recordings.reading(t, zero, "unloaded", 0.0)
    assert row["deviation_n"] == 0.0 and row["n_unloaded"] == len(t)
    with pytest.raises(InputError, match="no weight was placed"):
        recordings.reading(t, zero, "loaded", 4.905, source="loaded_t05.parquet")


# ================================ tool rig: ADC rails and gel depth ==============================

def _tool_spec(params):
    from tactilepipe.tool import sim as tsim
    return tsim.session_plan(params)[0]


def test_nano17_beyond_range_clips_at_the_adc_rails(smoke_params):
    from tactilepipe.tool.formats import native_layout as layout
    from tactilepipe.tool import sim as tsim
    p = copy.deepcopy(smoke_params)
    p["simulate_tool"]["press"]["peak_force_n"] = [80.0, 120.0]     # beyond +-33.6 N of the 10-bit span
    trial = tsim.Trial(_tool_spec(p), p)
    ser = trial.serial()
    counts = ser["counts"]
    assert counts.min() >= 0 and counts.max() <= layout.ADC_COUNTS
    assert ser["clipped"] > 0 and (counts == layout.ADC_COUNTS).any() | (counts == 0).any()
    force = (layout.counts_to_volts(counts) - trial.rig["gauge_bias_v"]) @ tsim.calibration_matrix(p).T
    assert np.isfinite(force).all()
    assert np.abs(force[:, 2]).max() < np.abs(ser["wrench"][:, 2]).max()    # read as less than the truth
    normal = tsim.Trial(_tool_spec(smoke_params), smoke_params).serial()
    assert normal["clipped"] == 0


def test_tool_ingest_reports_adc_saturation(smoke_params, tmp_path):
    from tactilepipe.tool import sim as tsim
    from tactilepipe.tool.formats.serial_log import read_serial_log
    p = copy.deepcopy(smoke_params)
    p["simulate_tool"]["press"]["peak_force_n"] = [80.0, 120.0]
    ser = tsim.Trial(_tool_spec(p), p).serial()
    path = tmp_path / "force.log"
    path.write_text("\n".join(ser["lines"]) + "\n")
    log = read_serial_log(path)
    assert getattr(log, "saturated", 0) == ser["clipped"]


def test_saturated_nano17_samples_are_dropped_counted_and_shown(smoke_params, tmp_path):
    """Through the native import, ingest, dataset and QC report: no clipped force reaches a label."""
    from tactilepipe.tool.formats import native_layout as layout
    from tactilepipe.tool import sim as tsim
    from tactilepipe.tool.data.dataset import build_tool_dataset
    from tactilepipe.tool.formats.trials import open_trial
    from tactilepipe.tool.data.ingest import ingest_trial, read_shard_info
    from tactilepipe.tool.report.data import qc_markdown
    from tactilepipe.tool.formats.serial_log import read_serial_log
    p = copy.deepcopy(smoke_params)
    p["simulate_tool"]["press"]["peak_force_n"] = [80.0, 120.0]
    spec = _tool_spec(p)
    ser = tsim.Trial(spec, p).serial()
    at_rails = ((ser["counts"] == 0) | (ser["counts"] == layout.ADC_COUNTS)).any(axis=1)
    assert at_rails.sum() > 0
    tool_sim.write_session(tmp_path / "raw", p, trials=[spec.name])
    trial = tmp_path / "raw" / spec.name
    log = read_serial_log(trial / "force.log")
    assert log.saturated == at_rails.sum() and len(log.counts) == (~at_rails).sum()
    assert log.counts.min() > 0 and log.counts.max() < layout.ADC_COUNTS
    info = ingest_trial(open_trial(trial, "native"), tmp_path / "s.parquet", 32, p["tool_ingest"])
    assert info["drops"] == read_shard_info(tmp_path / "s.parquet")["drops"] == {
        "serial: ADC saturated": int(at_rails.sum())}
    assert info["force_samples"] == (~at_rails).sum()
    sync = p["tool_sync"]
    qc = build_tool_dataset([tmp_path / "s.parquet"], "normal", tmp_path / "data", sync)
    assert qc["trials"][0]["drops"]["serial: ADC saturated"] == at_rails.sum()
    md = qc_markdown(json.loads((tmp_path / "data" / "qc.json").read_text()), "normal")
    assert f"serial: ADC saturated: {at_rails.sum()}" in md
    assert f"**Nano17 saturated:** {at_rails.sum()} force samples at the ADC rails" in md


def test_a_gauge_stuck_at_a_rail_is_an_error(tmp_path):
    from tactilepipe.tool.formats.serial_log import read_serial_log
    path = tmp_path / "force.log"
    path.write_text("# start_host_ns=1000\n" + "".join(f"{100 + 67 * i},512,512,1023,512,512,512\n"
                                                         for i in range(20)))
    with pytest.raises(InputError, match=r"all 20 samples have a gauge channel at the ADC rails "
                                         r"\(count 0 or 1023; channel\(s\) \[2\] in every one\)"):
        read_serial_log(path)
    # rails on a few samples are dropped and counted, not an error, however many there are
    path.write_text("# start_host_ns=1000\n" + "".join(f"{100 + 67 * i},512,{0 if i % 2 else 512},512,512,512,512\n"
                                                         for i in range(20)))
    log = read_serial_log(path)
    assert log.saturated == 10 and dict(log.drops) == {"ADC saturated": 10} and len(log.counts) == 10


@pytest.mark.parametrize("e_star", [1.0, 1000.0])
def test_gel_depth_saturates_at_h_max_for_heavy_presses_and_stiff_gels(smoke_params, e_star):
    p = copy.deepcopy(smoke_params)
    p["simulate_tool"]["grasp"]["e_star_mpa"] = e_star
    out = tool_sim.render_at_forces(_tool_spec(p), p, normal_n=[0.0, 30.0, 3000.0])
    h_max = p["simulate_tool"]["render"]["h_max_mm"]
    for name, h in out["gel_height"].items():
        assert np.isfinite(h).all() and h.max() <= h_max + 1e-6, name
        assert out[name].dtype == np.uint8
    for key in ("depth", "normal_n", "shear_n"):
        assert np.isfinite(out["pads"][key]).all()


# ================================ metrics: undefined R² ==========================================

def test_r2_undefined_cases_have_a_reason():
    assert r2_detail([5.0, 5.0, 5.0], [5.0, 4.0, 6.0]) == (pytest.approx(float("nan"), nan_ok=True), R2_CONSTANT)
    value, reason = r2_detail([0.1, 0.1, 0.1], [0.1, 0.2, 0.0])      # round-off "variance"
    assert math.isnan(value) and reason == R2_CONSTANT
    assert r2_detail([], [])[1] == R2_EMPTY
    assert r2_detail([1.0, np.inf], [1.0, 2.0])[1] == R2_NONFINITE
    assert r2_detail([1.0, 2.0], [np.nan, 2.0])[1] == R2_NONFINITE
    assert r2_detail([3.0, 3.0], [np.nan, 2.0])[1] == R2_CONSTANT          # the labels decide first
    assert math.isnan(r2_score([1e-3] * 7, np.arange(7.0)))
    assert r2_detail([1e-3, 1e3], [1e-3, 1e3]) == (1.0, None)
    assert r2_score([1e-300, 2e-300, 3e-300], [1e-300, 2e-300, 3e-300]) == pytest.approx(1.0)
    assert format_metric(float("nan")) == "undefined" and format_metric(None) == "undefined"
    assert format_metric(0.98765) == "0.9877"


def test_tables_show_undefined(tmp_path):
    table = pd.DataFrame({"method": ["a", "b"], "r2": [0.5, float("nan")], "n": [3, 0], "note": ["", None]})
    write_table(table, tmp_path / "t", "T")
    md = (tmp_path / "t.md").read_text()
    assert "| b | undefined | 0 | undefined |" in md and "nan" not in md.lower().replace("undefined", "")
    assert pd.read_csv(tmp_path / "t.csv")["r2"].isna().tolist() == [False, True]


def test_tables_show_each_number_once_and_as_html(tmp_path):
    table = pd.DataFrame({"method": ["a<b", "c"], "R² (mean ± std)": ["0.9000 ± 0.0100", "undefined"],
                          "r2_mean": [0.9, float("nan")], "n": [3, 0]})
    write_table(table, tmp_path / "t", "Table & title", machine_only=("r2_mean",))
    assert list(pd.read_csv(tmp_path / "t.csv").columns) == ["method", "R² (mean ± std)", "r2_mean", "n"]
    md = (tmp_path / "t.md").read_text()
    assert "r2_mean" not in md and "| a<b | 0.9000 ± 0.0100 | 3 |" in md
    page = (tmp_path / "t.html").read_text()
    assert "<caption>Table &amp; title</caption>" in page and "<td>a&lt;b</td>" in page and "r2_mean" not in page
    assert '<td class="num">0.9000 ± 0.0100</td>' in page and "<td>undefined</td>" in page
    with pytest.raises(ValueError, match="lacks"):
        write_table(table, tmp_path / "u", "T", machine_only=("r2_median",))


def test_volume_report_formats_undefined_r2():
    from tactilepipe.volume import report
    s = report._summary(pd.DataFrame({"fold": [0, 1, 2], "r2": [float("nan")] * 3}), 0.4)
    assert math.isnan(s["mean"]) and s["undefined_folds"] == 3
    assert report._r2_text(s).startswith("undefined (the true values are constant")
    part = report._summary(pd.DataFrame({"fold": [0, 1, 2], "r2": [0.9, float("nan"), 0.7]}), 0.4)
    assert part["mean"] == pytest.approx(0.8) and "1 of 3 folds undefined" in report._r2_text(part)
    assert all(math.isnan(v) for v in s["ci95"])                  # no interval without two defined folds
    assert part["ci95"][0] < 0.8 < part["ci95"][1]                  # two defined folds: an interval
    assert report._json_safe({"a": float("nan"), "b": [np.float64(np.inf), 1.0]}) == {"a": None, "b": [None, 1.0]}


# ================================ one class, wide label ranges ===================================

def _one_class(volume: float = 100.0, lifts: int = 6) -> pd.DataFrame:
    rng = np.random.default_rng(0)
    return pd.concat([pd.DataFrame({"lift": f"v{volume:g}_{i}", "volume_ml": volume, "set": "main",
                                    "fx0": 0.01 * rng.standard_normal(30), "fy0": 0.8 + 0.01 * rng.standard_normal(30),
                                    "fz0": 6 + 0.1 * rng.standard_normal(30)}) for i in range(lifts)],
                     ignore_index=True)


def test_single_class_scene(smoke_params):
    data = _one_class()
    with pytest.raises(InputError, match="need at least two volumes"):
        make_folds(data.drop_duplicates("lift"), 2, 3, 2, seed=0)
    # folds made by hand (e.g. a real session with one volume): no crash, undefined with a reason
    folds = [{"fold": 0, "train": [f"v100_{i}" for i in range(4)], "test": ["v100_4", "v100_5"]}]
    res = baseline.sweep(data, folds, 0, smoke_params["baseline"])
    assert math.isnan(res["mu_star"]) and math.isnan(res["optima"]["mu_opt"][0])
    assert "no optimum: R² undefined" in res["optima"]["note"][0]
    assert math.isnan(res["summary"]["r2"][0]) and res["summary"]["r2_note"][0] == R2_CONSTANT
    model = MLPRegressor(MLPConfig(max_iter=20), seed=0).fit(data[["fy0", "fz0"]].to_numpy(), data["volume_ml"])
    pred = model.predict(data[["fy0", "fz0"]].to_numpy())
    assert model.constant_target and np.allclose(pred, 100.0)
    assert r2_detail(data["volume_ml"], pred)[1] == R2_CONSTANT


def test_labels_from_1e_minus_3_to_1e3_newtons():
    from tactilepipe.tool.model.evaluate import evaluate
    rng = np.random.default_rng(1)
    y = 10 ** rng.uniform(-3, 3, 3000)                        # N, six decades
    x = np.c_[y * (1 + 0.01 * rng.standard_normal(len(y))), rng.standard_normal(len(y))]
    cfg = MLPConfig(max_iter=100, restarts=2, learning_rate=0.01)
    model = MLPRegressor(cfg, seed=3).fit(x, y)
    pred = model.predict(x)
    assert np.isfinite(pred).all() and model.loss_curve and np.isfinite(model.loss_curve).all()
    assert r2_score(y, pred) > 0.99
    # standardisation makes training scale-free: the same fit in mN or kN, to float round-off
    for scale in (1e-6, 1e3):
        scaled = MLPRegressor(cfg, seed=3).fit(x * scale, y * scale).predict(x * scale)
        np.testing.assert_allclose(scaled, pred * scale, rtol=1e-6, atol=1e-9 * scale)
    result = evaluate(pd.DataFrame({"true": y, "pred": pred, "tool": "t"}))
    assert sum(w["n"] for w in result["per_window"]) == len(y)
    assert all(math.isfinite(v) for v in (result["mae"], result["rmse"], result["r2"]))


# ================================ NaN / inf reaching a loss ======================================

def test_mlp_stops_on_a_non_finite_loss_naming_epoch_and_batch():
    rng = np.random.default_rng(0)
    x = rng.standard_normal((450, 2))
    with pytest.raises(MLPDivergedError, match=r"non-finite loss \((inf|nan)\) at epoch 1, batch \d+ of 3 "
                                               r"\(restart \d of 3\)") as info:
        MLPRegressor(MLPConfig(learning_rate=1e250, max_iter=5), seed=0).fit(x, 3 * x[:, 0])
    assert isinstance(info.value, TactilepipeError)          # the CLI prints it as one line
    x[7, 1] = np.inf
    with pytest.raises(ValueError, match=r"NaN or inf \(1 samples, first rows \[7\]\)"):
        MLPRegressor(MLPConfig(max_iter=2), seed=0).fit(x, x[:, 0])


def test_tool_training_stops_on_an_inf_label_naming_epoch_and_batch(tmp_path):
    """tool/model/train.py: an inf label (not only NaN, tested in test_tool_model) stops training with
    the epoch, the batch and the sample index."""
    pytest.importorskip("torch")
    from support.tool_data import make_dataset, make_split_dict, quick_cfg

    from tactilepipe.tool.data.loader import ToolFrames
    from tactilepipe.tool.model.train import train
    root = make_dataset(tmp_path / "inf")
    samples = pd.read_parquet(root / "samples.parquet")
    samples.loc[5, "normal"] = np.inf
    samples.to_parquet(root / "samples.parquet", index=False)
    data = ToolFrames(root, "normal")
    split = make_split_dict(data)
    with pytest.raises(TactilepipeError, match=r"non-finite training loss \(inf\) at epoch 1, batch \d+: "
                                               r"non-finite labels at sample indices \[5\]"):
        train(data, split, quick_cfg(max_epochs=1), tmp_path / "run", progress=False)


# ================================ mu optimum on the edge =========================================

def _formula_data(mu_true: float, p: dict) -> tuple[pd.DataFrame, list[dict]]:
    return baseline_data(mu_true, p, seed=0)       # samples that follow the baseline formula exactly


@pytest.mark.parametrize("mu_true,side", [(0.55, "upper"), (0.02, "lower")])
def test_mu_optimum_on_the_edge_is_flagged(smoke_params, mu_true, side, tmp_path):
    from tactilepipe.volume import figures
    p = smoke_params["baseline"]
    res = baseline.sweep(*_formula_data(mu_true, p), 0, p)
    assert res["on_edge"] and res["optima"]["on_edge"].all()
    assert len(res["warnings"]) == len(res["optima"])
    assert all(f"on the {side} edge of the swept range" in w for w in res["warnings"])
    inside = baseline.sweep(*_formula_data(0.25, p), 0, p)
    assert not inside["on_edge"] and inside["warnings"] == []
    figures.mu_curves(res["curve"], res["optima"], res["mu_star"], tmp_path / "mu.png",
                      warning="optimum on the edge of the swept range")
    assert (tmp_path / "mu.png").read_bytes()[:4] == b"\x89PNG"


# ================================ skewed force distributions =====================================

def test_skewed_forces_get_per_window_metrics_with_counts(tmp_path):
    from tactilepipe.tool.model.evaluate import WINDOW_EDGES, evaluate
    rng = np.random.default_rng(2)
    true = np.concatenate([rng.exponential(1.0, 5000), [25.0, 40.0], [-0.2]])   # almost all light, 2 heavy
    pred = true + rng.normal(0, 0.3, len(true))
    result = evaluate(pd.DataFrame({"true": true, "pred": pred, "tool": "t"}))
    windows = pd.DataFrame(result["per_window"])
    assert len(windows) == len(WINDOW_EDGES)                      # every window listed, empty ones too
    assert windows["n"].sum() == len(true)
    expected, _ = np.histogram(np.clip(true, 0, None), WINDOW_EDGES + [np.inf])
    assert windows["n"].tolist() == expected.tolist()
    assert windows["n"].iloc[-1] == 2 and windows["n"].iloc[0] > 4000
    empty = windows[windows["n"] == 0]
    assert len(empty) > 0 and empty["mae"].isna().all()            # no samples: no MAE, not 0
    write_table(windows, tmp_path / "w", "per window")
    assert "| undefined |" in (tmp_path / "w.md").read_text()
