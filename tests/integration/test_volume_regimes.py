"""Grasp regimes of the volume simulator (force, position, retighten, sensor cross-talk) and the
regime comparison of Table 1 at the smoke scale."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tactilepipe.papillarray import physics
from tactilepipe.cli.main import main
from tactilepipe.core.errors import ConfigError
from tactilepipe.volume import grasp
from tactilepipe.volume import simulate as vsim
from tactilepipe.volume.regimes import PAPER_R2, reproduces_ordering

from support.project import REPO

VOLUMES = [0.0, 100.0, 200.0, 300.0]


def _lift(volume: float, index: int = 1) -> vsim.Lift:
    return vsim.Lift(f"v{int(volume):03d}_main_l{index:02d}", volume, "main", 0, index)


def _off_table_fz(rec: dict, sensor: int = 0) -> float:
    """Mean global Fz of one sensor while the container is off the table."""
    return float(rec["force"][rec["off_table"], sensor, :, 2].sum(axis=1).mean())


@pytest.fixture
def exact_sim(quiet_sim) -> dict:
    """The quiet smoke rig without creep, so the readings are the true forces, and without the
    position regime's lift-to-lift squeeze spread (as quiet_sim has no grip-force spread)."""
    return {**quiet_sim, "creep_fractions": [], "creep_tau_s": [],
            "position": {**quiet_sim["position"], "squeeze_std_mm": 0.0}}


# --- force: the grip is the setting, whatever the load --------------------------------------------

def test_force_regime_grip_does_not_depend_on_volume(exact_sim):
    fz = [_off_table_fz(vsim.simulate_lift(_lift(v), exact_sim, 2026)) for v in VOLUMES]
    np.testing.assert_allclose(fz, exact_sim["grip_force_n"], rtol=1e-5)


def test_force_regime_mean_fz_per_lift_has_no_volume_trend(vsim_params):
    """With every measurement error on: the lift-to-lift spread of Fz, not the volume, moves it."""
    sim = {**vsim_params, "drift_inf_n": 0.0, "drift_per_kg_n": 0.0}
    vols = np.repeat(VOLUMES, 4)
    fz = np.array([_off_table_fz(vsim.simulate_lift(_lift(v, i % 4), sim, 2026)) for i, v in enumerate(vols)])
    slope = np.polyfit(vols, fz, 1)[0]
    # 3 standard errors of a slope fitted to the grip's lift-to-lift spread alone
    spread = sim["grip_force_n"] * sim["grip_force_rel_std"]
    assert abs(slope) < 3 * spread / np.sqrt(((vols - vols.mean()) ** 2).sum())


# --- position: the squeeze meets pads and wall in series; less headspace, stiffer wall ------------

def test_position_regime_fz_rises_with_fill_level(exact_sim):
    sim = {**exact_sim, "grip_regime": "position"}
    fz = np.array([_off_table_fz(vsim.simulate_lift(_lift(v), sim, 2026)) for v in VOLUMES])
    assert np.all(np.diff(fz) > 0), fz
    # the rise is the headspace's: it grows as the air above the water shrinks
    assert fz[3] - fz[2] > fz[1] - fz[0]


def test_position_grip_solves_the_series_springs(exact_sim):
    pos = exact_sim["position"]
    offsets = physics.pillar_offsets_mm(exact_sim["pillar_height_steps_mm"])
    k_n = exact_sim["pillar_normal_stiffness_n_per_mm"]
    for volume in (0.0, 250.0):
        force = grasp.position_grip_n(pos, volume, pos["squeeze_mm"], offsets, k_n)
        k_wall = grasp.wall_stiffness_n_per_mm(pos, volume)
        squeeze = 2 * grasp.pad_indentation_mm(force, offsets, k_n) + force / k_wall
        assert squeeze == pytest.approx(pos["squeeze_mm"], rel=1e-9)
        # the pad's indentation carries exactly that force on its pillars
        depth = grasp.pad_indentation_mm(force, offsets, k_n)
        assert k_n * np.clip(depth - offsets, 0, None).sum() == pytest.approx(force, rel=1e-9)


def test_open_container_wall_ignores_the_fill_level(exact_sim):
    pos = {**exact_sim["position"], "container_capped": False}
    assert grasp.wall_stiffness_n_per_mm(pos, 0.0) == grasp.wall_stiffness_n_per_mm(pos, 300.0)
    sim = {**exact_sim, "grip_regime": "position", "position": pos}
    fz = [_off_table_fz(vsim.simulate_lift(_lift(v), sim, 2026)) for v in (0.0, 300.0)]
    assert fz[0] == pytest.approx(fz[1], rel=1e-6)


def test_ring_stiffness_hand_value():
    pos = {"wall_modulus_mpa": 3000.0, "wall_contact_length_mm": 12.0, "wall_thickness_mm": 1.0,
           "container_radius_mm": 10.0, "container_capped": True, "container_capacity_ml": 1.0,
           "dimple_area_mm2": 100.0, "atmospheric_kpa": 100.0}
    ring = 3000.0 * 1.0 / (0.1488 * 1000.0)            # E I / (0.1488 R^3) with I = 12 * 1 / 12
    gas = 0.1 * 100.0**2 / 1000.0                      # p0 A^2 / V_air, 1 ml of air
    assert grasp.wall_stiffness_n_per_mm(pos, 0.0) == pytest.approx(ring + gas)


# --- retighten: the grip stays at the setting until a loaded pillar slips, then rises -------------

def _first_loaded_slip(rec: dict) -> int:
    loaded = rec["slip"] & (rec["true_force"][..., 2] > vsim.CONTACT_N)
    hits = np.flatnonzero(loaded.any(axis=(1, 2)))
    return int(hits[0]) if len(hits) else -1


def test_retighten_raises_the_grip_only_after_slip_onset(exact_sim):
    sim = {**exact_sim, "grip_regime": "retighten"}
    lag = int(round(sim["retighten"]["latency_s"] * sim["rate_hz"]))
    setting = vsim.simulate_lift(_lift(300.0), exact_sim, 2026)["grip"]     # the force regime's grip
    rec = vsim.simulate_lift(_lift(300.0), sim, 2026)
    onset = _first_loaded_slip(rec)
    assert 0 < onset < len(rec["t"]) - lag
    # up to the slip onset plus the detection latency the grip is the force setting's, sample for sample
    np.testing.assert_array_equal(rec["grip"][: onset + lag], setting[: onset + lag])
    assert rec["grip"][onset + lag] > setting[onset + lag]
    held = rec["grip"][rec["off_table"]]
    assert held.min() > sim["grip_force_n"]
    assert np.all(np.diff(held) >= 0)                  # never lowered while the container is held


def test_retighten_grip_grows_with_load(exact_sim):
    sim = {**exact_sim, "grip_regime": "retighten"}
    fz = np.array([_off_table_fz(vsim.simulate_lift(_lift(v), sim, 2026)) for v in VOLUMES])
    force_fz = _off_table_fz(vsim.simulate_lift(_lift(0.0), exact_sim, 2026))
    assert fz[0] == pytest.approx(force_fz, rel=1e-6)  # the empty container never slips a loaded pillar
    assert fz[-1] > fz[0] + 0.3
    assert np.all(np.diff(fz) >= -1e-9)


def test_retighten_respects_the_grip_limit(exact_sim):
    sim = {**exact_sim, "grip_regime": "retighten",
           "retighten": {**exact_sim["retighten"], "max_grip_n": exact_sim["grip_force_n"] + 0.1}}
    rec = vsim.simulate_lift(_lift(300.0), sim, 2026)
    assert rec["grip"].max() == pytest.approx(sim["grip_force_n"] + 0.1)


# --- cross-talk: the sensor adds the set fraction of each pillar's shear to its normal force -----

@pytest.mark.parametrize("fraction", [0.05, 0.3])
def test_crosstalk_adds_the_set_fraction_of_the_shear(exact_sim, fraction):
    clean = vsim.simulate_lift(_lift(300.0), exact_sim, 2026)
    talk = vsim.simulate_lift(_lift(300.0), {**exact_sim, "crosstalk_t_to_n": fraction}, 2026)
    shear = np.linalg.norm(clean["true_force"][..., :2], axis=-1)
    added = talk["force"][..., 2].astype(np.float64) - clean["force"][..., 2]
    np.testing.assert_allclose(added, fraction * shear, atol=2e-6)
    np.testing.assert_array_equal(talk["force"][..., :2], clean["force"][..., :2])
    assert added[clean["off_table"]].sum(axis=-1).mean() > 0


# --- configuration --------------------------------------------------------------------------------

def test_capped_container_needs_headspace(params_path):
    from tactilepipe.studies import load_params
    with pytest.raises(ConfigError, match="container_capacity_ml"):
        load_params(params_path, {"simulate_volume": {"position": {"container_capacity_ml": 300.0}}})


def test_a_regime_may_only_change_grasp_keys(params_path):
    from tactilepipe.studies import load_params
    with pytest.raises(ConfigError, match="volume_regimes"):
        load_params(params_path, {"volume_regimes": {"heavy": {"container_mass_g": 100.0}}})


def test_analysis_code_never_reads_the_simulator_settings():
    """The regime is a property of the recordings only: a real session runs through the same code."""
    volume = REPO / "src" / "tactilepipe" / "volume"
    for name in ("dataset.py", "folds.py", "train.py", "mlp.py", "baseline.py", "report.py", "figures.py"):
        text = (volume / name).read_text()
        for key in ("simulate_volume", "grip_regime", "crosstalk_t_to_n"):
            assert key not in text, f"{name} reads {key}"


def test_paper_table_has_the_paper_ordering():
    assert reproduces_ordering({m: {"mean": v[0]} for m, v in PAPER_R2.items()})
    assert not reproduces_ordering({"fz": {"mean": 0.0}, "fy": {"mean": 0.98}, "fy_fz": {"mean": 0.98}})


# --- the comparison at the smoke scale, through the CLI -------------------------------------------

@pytest.fixture(scope="module")
def comparison(tmp_path_factory, smoke_params) -> Path:
    out = tmp_path_factory.mktemp("regimes") / "out"
    code = main(["volume-regimes", "--params", str(REPO / "params.yaml"), "--scale", "smoke",
                 "--out-dir", str(out), "--jobs", "1", "--regimes", "force", "position", "retighten"])
    assert code == 0
    return out


def test_comparison_writes_tables_figures_and_metrics(comparison):
    table = pd.read_csv(comparison / "table1_regimes.csv")
    assert list(table["regime"]) == ["force", "position", "retighten", "paper"]
    paper = table.set_index("regime").loc["paper"]
    assert paper["fz_mean"] == 0.9842 and paper["mu_star"] == 0.268
    md = (comparison / "table1_regimes.md").read_text()
    assert "| paper |" in md and "0.984 ± 0.005" in md
    for fig in ("r2_by_regime.png", "fz_vs_volume.png"):
        assert (comparison / "figures" / fig).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    metrics = json.loads((comparison / "metrics.json").read_text())
    assert set(metrics["regimes"]) == {"force", "position", "retighten"}
    assert not list(comparison.glob(".scratch-*"))       # bags and shards are not left behind


def test_comparison_shows_each_regimes_physics(comparison):
    metrics = json.loads((comparison / "metrics.json").read_text())
    force, position = (metrics["regimes"][r]["r2"] for r in ("force", "position"))
    assert force["fz"]["mean"] < 0.3 < force["fy"]["mean"]     # force control: Fz carries no volume
    assert position["fz"]["mean"] > force["fz"]["mean"] + 0.3  # position: the grip carries the fill
    grip = pd.read_csv(comparison / "fz_vs_volume.csv").set_index(["regime", "volume_ml"])
    for phase in ("fz_before", "fz", "fz_after"):       # the squeeze is set before the lift
        assert grip.loc[("position", 300.0), f"{phase}_mean_n"] > grip.loc[("position", 0.0), f"{phase}_mean_n"] + 0.5
    # retighten: the grip is the setting on the table before lift-off and rises only under the load
    rt = grip.loc["retighten"]
    assert abs(rt.loc[300.0, "fz_before_mean_n"] - rt.loc[0.0, "fz_before_mean_n"]) < 0.45
    assert rt.loc[300.0, "fz_mean_n"] > rt.loc[300.0, "fz_before_mean_n"] + 0.3
    assert rt.loc[300.0, "fz_after_mean_n"] > rt.loc[300.0, "fz_before_mean_n"] + 0.3   # kept until opening
    qc = pd.read_csv(comparison / "qc_force.csv")
    assert qc[["fz_before_lift", "fz_held", "fz_after_place"]].notna().all().all()
    # force control: the grip before lift-off is the grip held, lift by lift (drift and noise apart)
    np.testing.assert_allclose(qc["fz_held"], qc["fz_before_lift"], atol=0.15)


def test_unknown_regime_is_refused(tmp_path, capsys):
    code = main(["volume-regimes", "--params", str(REPO / "params.yaml"), "--scale", "smoke",
                 "--out-dir", str(tmp_path), "--regimes", "nosuch"])
    assert code == 2
    assert "nosuch" in capsys.readouterr().err
