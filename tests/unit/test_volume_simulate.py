"""Lift simulator of study 001: determinism, the physics of the carried load, grip, pillar load map,
stick/slip, minimum-jerk motion, measurement noise and drift, and the session labels."""

from __future__ import annotations

import numpy as np
import pytest

from tactilepipe.papillarray import physics
from tactilepipe.volume.labels import read_session_labels
from tactilepipe.core.errors import InputError
from tactilepipe.volume import simulate as vsim

G = physics.G


def _hold(rec: dict) -> np.ndarray:
    t0, t1 = rec["phases"]["hold"]
    return (rec["t"] >= t0) & (rec["t"] < t1)


def _acc(rec: dict, sim: dict) -> np.ndarray:
    """The tool's vertical acceleration, rebuilt from the phase table (lift and place moves)."""
    t, ph = rec["t"], rec["phases"]
    lift_s = ph["lift"][1] - ph["lift"][0]
    _, a_up = physics.minimum_jerk(t - ph["lift"][0], lift_s, sim["lift_height_m"])
    _, a_dn = physics.minimum_jerk(t - ph["place"][0], lift_s, sim["lift_height_m"])
    return a_up - a_dn


def _mass_kg(sim: dict, volume_ml: float) -> float:
    return (sim["container_mass_g"] + volume_ml) / 1000.0


def _lift(volume: float, index: int = 0, kind: str = "main") -> vsim.Lift:
    return vsim.Lift(f"v{int(volume):03d}_{kind}_l{index:02d}", volume, kind, 0, index)


# --- session plan and determinism ---------------------------------------------------------------

def test_session_plan_lists_every_lift_once(vsim_params):
    plan = vsim.session_plan(vsim_params)
    n_main = len(vsim_params["volumes_ml"]) * vsim_params["lifts_per_volume"]
    n_unseen = len(vsim_params["unseen_volumes_ml"]) * vsim_params["unseen_lifts_per_volume"]
    assert len(plan) == n_main + n_unseen == 7 * 5 + 2 * 2
    assert len({l.name for l in plan}) == len(plan)
    assert plan[0] == vsim.Lift("v000_main_l00", 0.0, "main", 0, 0)
    assert plan[-1] == vsim.Lift("v125_unseen_l01", 125.0, "unseen", 8, 1)
    assert [l.kind for l in plan] == ["main"] * n_main + ["unseen"] * n_unseen
    for l in plan:   # one block per volume, lifts numbered within the block
        assert l.block == (vsim_params["volumes_ml"] + vsim_params["unseen_volumes_ml"]).index(l.volume_ml)
    assert [l.index for l in plan if l.volume_ml == 50] == list(range(vsim_params["lifts_per_volume"]))


def test_same_seed_gives_byte_identical_bags_and_another_seed_does_not(tmp_path, smoke_params):
    sim, seed = smoke_params["simulate_volume"], smoke_params["seed"]
    lift = _lift(100.0, 2)
    vsim.write_lift_bag(tmp_path / "a" / "x.bag", lift, sim, seed)
    vsim.write_lift_bag(tmp_path / "b" / "x.bag", lift, sim, seed)
    vsim.write_lift_bag(tmp_path / "c" / "x.bag", lift, sim, seed + 1)
    vsim.write_lift_bag(tmp_path / "d" / "x.bag", _lift(100.0, 3), sim, seed)
    first = (tmp_path / "a" / "x.bag").read_bytes()
    assert first == (tmp_path / "b" / "x.bag").read_bytes()
    assert first != (tmp_path / "c" / "x.bag").read_bytes()
    assert first != (tmp_path / "d" / "x.bag").read_bytes()     # another lift of the same volume
    assert list(tmp_path.rglob("*.tmp")) == []


def test_simulate_lift_is_deterministic(vsim_params):
    a = vsim.simulate_lift(_lift(50.0, 1), vsim_params, 7)
    b = vsim.simulate_lift(_lift(50.0, 1), vsim_params, 7)
    c = vsim.simulate_lift(_lift(50.0, 1), vsim_params, 8)
    np.testing.assert_array_equal(a["force"], b["force"])
    np.testing.assert_array_equal(a["pose_z"], b["pose_z"])
    assert not np.array_equal(a["force"], c["force"])


# --- carried load ---------------------------------------------------------------------------------

@pytest.mark.parametrize("volume", [0.0, 150.0, 300.0])
def test_pads_carry_m_g_plus_a_while_off_table(quiet_sim, volume):
    """Off the table the two pads together carry exactly m(g + a) (shear magnitude), split about
    evenly between the sensors (the tangential stiffness mismatch is <= 3 %)."""
    rec = vsim.simulate_lift(_lift(volume), quiet_sim, 11)
    off = rec["off_table"]
    assert off.sum() > 2.0 * quiet_sim["rate_hz"]          # the hold alone is 1.4 s
    want = _mass_kg(quiet_sim, volume) * (G + _acc(rec, quiet_sim))
    g = rec["force"].astype(np.float64).sum(axis=2)        # (T, sensor, xyz) global forces
    shear = np.hypot(g[..., 0], g[..., 1])                 # (T, sensor)
    np.testing.assert_allclose(shear.sum(axis=1)[off], want[off], rtol=1e-4)
    # the grasp tilt (std 1.5 deg) puts only a sliver of the load on x
    assert (g[off, :, 1].sum(axis=1) / want[off]).min() > np.cos(np.deg2rad(6))
    # each sensor carries half within the stiffness mismatch
    hold = _hold(rec)
    half = _mass_kg(quiet_sim, volume) * G / 2
    np.testing.assert_allclose(g[hold, :, 1].mean(axis=0), [half, half], rtol=0.03)
    assert not rec["gross_slip"].any()


def test_off_table_truth_lies_inside_the_lift(quiet_sim):
    rec = vsim.simulate_lift(_lift(200.0), quiet_sim, 3)
    t, off, ph = rec["t"], rec["off_table"], rec["phases"]
    assert off[_hold(rec)].all()
    assert not off[t < ph["lift"][0]].any() and not off[t > ph["place"][1]].any()
    # a single run: the container leaves once and comes back once
    assert np.count_nonzero(np.diff(off.astype(int)) == 1) == 1


def test_vertical_shear_grows_linearly_with_volume(quiet_sim):
    volumes = np.array([0.0, 100.0, 200.0, 300.0])
    fy = []
    for v in volumes:
        rec = vsim.simulate_lift(_lift(v), quiet_sim, 5)
        fy.append(rec["force"][_hold(rec)][..., 1].astype(np.float64).sum(axis=(1, 2)).mean())  # both sensors
    slope, icpt = np.polyfit(volumes, fy, 1)
    resid = np.asarray(fy) - (slope * volumes + icpt)
    assert slope == pytest.approx(G / 1000.0, rel=0.01)                       # N per ml of water
    assert icpt == pytest.approx(quiet_sim["container_mass_g"] * G / 1000.0, rel=0.01)
    assert np.abs(resid).max() < 0.005


def test_vertical_shear_with_measurement_errors(sim_lifts, smoke_params):
    """With noise, bias residual and drift, per-sensor hold Fy stays within the global bias residual
    (sum of 9 pillar residuals, std 0.03 N) of m g / 2; both sensors together rise ~ g per litre."""
    sim = smoke_params["simulate_volume"]
    volumes, totals = [], []
    for item in sim_lifts:
        rec, v = item["rec"], item["lift"].volume_ml
        fy = rec["force"][_hold(rec)][..., 1].astype(np.float64).sum(axis=2).mean(axis=0)   # (2,)
        assert np.abs(fy - _mass_kg(sim, v) * G / 2).max() < 0.12
        volumes.append(v)
        totals.append(fy.sum())
    slope = np.polyfit(volumes, totals, 1)[0]
    assert slope == pytest.approx(G / 1000.0, rel=0.06)


def test_grip_force_does_not_depend_on_volume(quiet_sim):
    """The Robotiq gripper is force controlled: it closes until each pad presses with the force
    setting, whatever the container weighs, so global Fz holds the grip, not the volume (the load
    is carried by friction, i.e. by shear)."""
    grip = quiet_sim["grip_force_n"]
    per_volume = []
    for v in (0.0, 300.0):
        rec = vsim.simulate_lift(_lift(v), quiet_sim, 9)
        fz = rec["force"][..., 2].astype(np.float64).sum(axis=2)       # (T, sensor)
        hold = _hold(rec)
        np.testing.assert_allclose(fz[hold], grip, rtol=1e-5)
        per_volume.append(fz[hold].mean(axis=0))
    np.testing.assert_allclose(per_volume[0], per_volume[1], rtol=1e-5)


def test_centre_pillar_carries_the_largest_normal_load(sim_lifts):
    for item in sim_lifts:
        rec = item["rec"]
        fz = rec["force"][_hold(rec)][..., 2].mean(axis=0)      # (sensor, pillar)
        assert (fz.argmax(axis=1) == 4).all(), fz
        assert fz[:, 4].min() > 1.5 * np.delete(fz, 4, axis=1).max()


def test_low_friction_makes_the_pad_slide(quiet_sim):
    slippery = {**quiet_sim, "friction_static": 0.15, "friction_kinetic": 0.1}
    rec = vsim.simulate_lift(_lift(300.0), slippery, 2)
    assert rec["gross_slip"][_hold(rec)].all()      # 3.5 N of weight vs 2 x 0.1 x 6 N of kinetic friction
    held = rec["force"][_hold(rec)].astype(np.float64)
    assert rec["slip"][_hold(rec)][held[..., 2] > 0].all()           # every pillar in contact slides
    shear = np.hypot(held[..., 0].sum(axis=2), held[..., 1].sum(axis=2))
    np.testing.assert_allclose(shear, 0.1 * quiet_sim["grip_force_n"], rtol=1e-5)   # the kinetic limit
    normal = vsim.simulate_lift(_lift(300.0), quiet_sim, 2)
    assert not normal["gross_slip"].any()


# --- normal load map --------------------------------------------------------------------------

def test_normal_load_map_sums_to_the_grip(vsim_params):
    rng = np.random.default_rng(0)
    grip = np.concatenate([[0.0, 1e-4, 0.3], rng.uniform(0, 20, 50)])
    offsets = physics.pillar_offsets_mm(vsim_params["pillar_height_steps_mm"])
    for tilt in ([0.0, 0.0], [0.02, -0.01], [-0.05, 0.04]):
        fz = physics.normal_load_map(grip, offsets, np.array(tilt), vsim_params["pillar_pitch_mm"],
                                  vsim_params["pillar_normal_stiffness_n_per_mm"])
        assert fz.shape == (len(grip), 9)
        assert (fz >= 0).all()
        np.testing.assert_allclose(fz.sum(axis=1), grip, rtol=1e-9, atol=1e-12)
        assert (fz[0] == 0).all()
        order = np.argsort(grip)                          # more grip never unloads a pillar
        assert (np.diff(fz[order], axis=0) >= -1e-9).all()
        assert (fz[grip > 1].argmax(axis=1) == 4).all()   # the centre is the tallest pillar


def test_normal_load_map_untilted_is_symmetric(vsim_params):
    offsets = physics.pillar_offsets_mm(vsim_params["pillar_height_steps_mm"])
    fz = physics.normal_load_map(np.array([6.0]), offsets, np.zeros(2), 3.5, 4.0)[0]
    edges, corners = fz[[1, 3, 5, 7]], fz[[0, 2, 6, 8]]
    np.testing.assert_allclose(edges, edges[0])
    np.testing.assert_allclose(corners, corners[0])
    assert fz[4] > edges[0] > corners[0] >= 0


# --- stick / slip -----------------------------------------------------------------------------

@pytest.fixture
def pad_fz(vsim_params) -> np.ndarray:
    offsets = physics.pillar_offsets_mm(vsim_params["pillar_height_steps_mm"])
    return physics.normal_load_map(np.array([6.0]), offsets, np.array([0.012, -0.007]),
                                vsim_params["pillar_pitch_mm"], vsim_params["pillar_normal_stiffness_n_per_mm"])[0]


def test_outer_pillars_slip_first_and_shear_equals_demand_while_any_sticks(pad_fz):
    mu_s, mu_k, k_t = 0.6, 0.45, 1.2
    n = 600
    demand = np.zeros((n, 2))
    demand[:, 1] = np.linspace(0.0, 1.3 * mu_s * pad_fz.sum(), n)      # a vertical load ramp
    fz = np.tile(pad_fz, (n, 1))
    forces, slipping, gross = vsim.tangential_forces(demand, fz, k_t, mu_s, mu_k)
    contact = pad_fz > 0
    assert contact.sum() >= 7
    first = np.array([np.argmax(slipping[:, i]) if slipping[:, i].any() else n for i in range(9)])
    assert slipping[:, contact].any(axis=0).all()                  # the ramp ends beyond static friction
    # the lower a pillar's normal load, the earlier it slips; the centre slips last
    c = np.flatnonzero(contact)
    by_load = c[np.argsort(pad_fz[c])]
    assert (np.diff(first[by_load]) >= 0).all(), (pad_fz[by_load], first[by_load])
    assert first[4] == first[c].max()
    assert first[by_load[0]] < first[4]
    # total pad shear equals the demand while at least one pillar sticks
    sticks = (~slipping & contact).any(axis=1)
    assert sticks[: n // 2].all()
    np.testing.assert_allclose(forces[sticks].sum(axis=1), demand[sticks], atol=1e-9)
    # a sliding pillar pulls with the kinetic limit, a sticking one stays within the static one
    mag = np.linalg.norm(forces, axis=2)
    np.testing.assert_allclose(mag[slipping], (mu_k * fz)[slipping], rtol=1e-9)
    assert (mag[~slipping] <= mu_s * fz[~slipping] + 1e-9).all()
    assert (forces[:, ~contact] == 0).all()


def test_gross_slip_flagged_when_demand_exceeds_kinetic_capacity(pad_fz):
    mu_s, mu_k, k_t = 0.6, 0.45, 1.2
    cap_k = mu_k * pad_fz.sum()
    n = 400
    demand = np.zeros((n, 2))
    demand[:, 0] = 0.3 * np.linspace(0.0, 2.0 * cap_k, n)
    demand[:, 1] = np.linspace(0.0, 2.0 * cap_k, n)
    want = np.linalg.norm(demand, axis=1)
    forces, slipping, gross = vsim.tangential_forces(demand, np.tile(pad_fz, (n, 1)), k_t, mu_s, mu_k)
    assert gross.any() and gross[-1]
    assert (want[gross] > cap_k).all()                     # only flagged beyond the kinetic capacity
    assert not gross[want <= cap_k].any()
    assert (gross == ~(~slipping[:, pad_fz > 0]).any(axis=1)).all()    # gross = every pillar slides
    total = forces[gross].sum(axis=1)
    np.testing.assert_allclose(np.linalg.norm(total, axis=1), cap_k, rtol=1e-9)   # carries only mu_k N
    np.testing.assert_allclose(total / np.linalg.norm(total, axis=1, keepdims=True),
                               demand[gross] / want[gross, None], atol=1e-9)       # along the demand


def test_no_grip_no_shear():
    forces, slipping, gross = vsim.tangential_forces(np.ones((5, 2)), np.zeros((5, 9)), 1.2, 0.6, 0.45)
    assert (forces == 0).all() and not slipping.any() and not gross.any()


# --- motion -----------------------------------------------------------------------------------

def test_minimum_jerk_starts_and_ends_at_rest_and_reaches_the_height():
    duration, height = 1.5, 0.1
    t = np.linspace(-0.5, 2.0, 25001)
    z, acc = physics.minimum_jerk(t, duration, height)
    dt = t[1] - t[0]
    vel = np.gradient(z, dt)
    start, end = np.argmin(np.abs(t)), np.argmin(np.abs(t - duration))
    assert z[t <= 0].max() == 0.0 and np.all(z[t >= duration] == pytest.approx(height))
    assert abs(vel[start]) < 1e-6 and abs(vel[end]) < 1e-6
    assert abs(acc[start]) < 1e-12 and abs(acc[end]) < 1e-9 * height
    assert (acc[(t < 0) | (t > duration)] == 0).all()
    assert (np.diff(z) >= 0).all()                                       # monotonic
    assert z[np.argmin(np.abs(t - duration / 2))] == pytest.approx(height / 2)
    # acc is the second derivative of z, peak 10/sqrt(3) h/D^2
    np.testing.assert_allclose(np.gradient(vel, dt)[10:-10], acc[10:-10], atol=2e-3 * height / duration**2 * 10)
    assert acc.max() == pytest.approx(10 / np.sqrt(3) * height / duration**2, rel=1e-4)
    assert vel.max() == pytest.approx(1.875 * height / duration, rel=1e-4)


def test_pose_follows_the_lift(vsim_params):
    rec = vsim.simulate_lift(_lift(100.0), vsim_params, 1)
    assert rec["pose_t"][1] - rec["pose_t"][0] == pytest.approx(1.0 / vsim_params["pose_rate_hz"])
    z = rec["pose_z"] - vsim.POSE_BASE_Z_M
    assert abs(np.median(z[:10])) < 1e-4
    assert z.max() == pytest.approx(vsim_params["lift_height_m"], abs=1e-4)


# --- measurement --------------------------------------------------------------------------------

def test_unloaded_pillar_noise_matches_noise_std(vsim_params):
    """Before the gripper closes (t < 0.3 s) every pillar is unloaded: what it reads is the bias
    residual (constant) plus white noise of std noise_std_n."""
    sim = {**vsim_params, "rate_hz": 500}
    rec = vsim.simulate_lift(_lift(150.0, 0), sim, 4)
    pre = rec["force"][rec["t"] < 0.3].astype(np.float64)               # (~150, 2, 9, 3)
    dev = pre - pre.mean(axis=0)
    std = np.sqrt((dev ** 2).sum() / (dev.size - dev[0].size))
    assert std == pytest.approx(sim["noise_std_n"], rel=0.05)
    assert np.abs(pre.mean(axis=0)).max() < 0.05                        # ~ +-0.02 N around zero
    assert not rec["in_contact"][rec["t"] < 0.3].any()


def test_thermal_drift_grows_with_time_since_bias(quiet_sim):
    sim = {**quiet_sim, "drift_inf_n": 0.35, "drift_per_kg_n": 0.0}
    for index in (0, 30):
        rec = vsim.simulate_lift(_lift(0.0, index), sim, 1)
        pre = rec["t"] < 0.3
        fz = rec["force"][pre][..., 2].astype(np.float64).sum(axis=2)   # global Fz of both sensors
        want = sim["drift_inf_n"] * (1 - np.exp(-(index * sim["lift_cycle_s"] + rec["t"][pre]) / sim["drift_tau_s"]))
        np.testing.assert_allclose(fz, np.repeat(want[:, None], 2, axis=1), atol=1e-5)


# --- labels ---------------------------------------------------------------------------------------

def test_session_labels_round_trip(tmp_path, vsim_params):
    plan = vsim.session_plan(vsim_params)
    vsim.write_session_labels(tmp_path, plan)
    rows = read_session_labels(tmp_path)
    assert rows == [{"bag": f"{l.name}.bag", "volume_ml": l.volume_ml, "set": l.kind} for l in plan]


@pytest.mark.parametrize("text, problem", [
    ("bag,volume\na.bag,1\n", "header must hold bag,volume_ml,set"),
    ("bag,volume_ml,set\na.bag,50,main\nb.bag,lots,main\n", r"\[line 3\]: volume_ml 'lots' is not a number"),
    ("bag,volume_ml,set\na.bag,-5,main\n", r"\[line 2\]: volume_ml -5.0 must be finite"),
    ("bag,volume_ml,set\na.bag,nan,main\n", r"\[line 2\]: volume_ml nan must be finite"),
    ("bag,volume_ml,set\na.bag,5,test\n", r"\[line 2\]: set 'test' must be main or unseen"),
    ("", "header must hold"),
])
def test_bad_session_labels_name_the_file_and_line(tmp_path, text, problem):
    (tmp_path / "lifts.csv").write_text(text)
    with pytest.raises(InputError, match=problem) as err:
        read_session_labels(tmp_path)
    assert str(tmp_path / "lifts.csv") in str(err.value)


def test_missing_session_labels(tmp_path):
    with pytest.raises(InputError, match="lifts.csv.*missing"):
        read_session_labels(tmp_path)
