"""DIGIT tool-force simulator of study 000: plan, determinism, files in the rig's layout, the
physics seen in the frames (imprint growth, finger asymmetry, saturation, preload), the Arduino
log through the calibration, the DIGIT look, and the public dataset layout (writer and reader)."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from support import public_formats, tool_sim
from support.project import REPO
from tactilepipe.core.config import deep_merge, load_params
from tactilepipe.core.errors import ConfigError, InputError
from tactilepipe.tool.sim import render as dr
from tactilepipe.tool.formats import native_layout as layout
from tactilepipe.tool.formats import public_layout as pl
from tactilepipe.tool import sim as ts

SEED = 2026
LSB_V = layout.ADC_VOLTS / layout.ADC_COUNTS


@pytest.fixture(scope="module")
def default_params() -> dict:
    return {"simulate_tool": load_params(REPO / "params.yaml", {"scale": "default"})["simulate_tool"],
            "seed": SEED}


@pytest.fixture(scope="module")
def group(default_params) -> dict:
    return default_params["simulate_tool"]


@pytest.fixture(scope="module")
def params() -> dict:
    """The smoke scale of params.yaml."""
    return {"simulate_tool": load_params(REPO / "params.yaml", {"scale": "smoke"})["simulate_tool"],
            "seed": SEED}


@pytest.fixture(scope="module")
def normal_spec(params) -> ts.TrialSpec:
    return next(s for s in ts.session_plan(params) if s.kind == "normal")


@pytest.fixture(scope="module")
def sim_normal(normal_spec, params) -> dict:
    return ts.simulate_trial(normal_spec, params)


@pytest.fixture(scope="module")
def written(tmp_path_factory, normal_spec, params) -> dict:
    """One smoke trial written twice with the seed and once with another seed."""
    root = tmp_path_factory.mktemp("tool_sessions")
    dirs = {}
    for key, seed in (("a", SEED), ("b", SEED), ("c", SEED + 1)):
        p = {**params, "seed": seed}
        ts.write_session_calibration(root / key, p)
        ts.write_trial(root / key, normal_spec, p)
        dirs[key] = root / key
    return dirs


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _spec_for(params: dict, tool: str, pose: int, kind: str = "normal") -> ts.TrialSpec:
    p = ts.plan.sim_group(params)["poses"][pose]
    return ts.TrialSpec(f"{tool}_p{pose:02d}_{kind}00", tool, kind, p["orientation_deg"], p["insertion_mm"], pose)


def _contact_change(out: dict, sensor: str) -> np.ndarray:
    """Mean |frame - reference| (summed over colours) over the contact area, per frame."""
    frames = out[sensor].astype(np.float32)
    ref, blank = frames[0], out["no_grasp"][sensor].astype(np.float32)
    mask = np.abs(ref - blank).sum(-1) > 6
    assert mask.mean() > 0.1, "the reference frame shows no handle imprint"
    return np.array([np.abs(f - ref).sum(-1)[mask].mean() for f in frames])


# --- plan and parameters ------------------------------------------------------------------------

def test_session_plan_smoke_and_default(params, default_params):
    smoke = ts.session_plan(params)
    assert [s.name for s in smoke][:4] == ["screwdriver_1_p00_normal00", "screwdriver_1_p00_shear00",
                                           "screwdriver_1_p01_normal00", "screwdriver_1_p01_shear00"]
    assert len(smoke) == 3 * 2 * 2 and {s.tool for s in smoke} == {"screwdriver_1", "paper_knife", "spatula"}
    assert [s.session_index for s in smoke] == list(range(len(smoke)))
    full = ts.session_plan(default_params)
    sim = default_params["simulate_tool"]
    assert len(full) == 4 * 3 * (8 + 4) and len({s.name for s in full}) == len(full)
    assert {s.tool for s in full} == {"screwdriver_1", "screwdriver_2", "paper_knife", "spatula"}
    assert sum(s.kind == "shear" for s in full) == 48
    n_normal_pairs = sum(s.kind == "normal" for s in full) * sim["frames_per_trial"]
    assert 8000 <= n_normal_pairs <= 12000
    assert sim["shear_frames_per_trial"] / 30.0 >= 4.0      # sliding trials long enough for several strokes
    for s in full:   # the recorded pose is the pose table's
        pose = sim["poses"][s.pose_index]
        assert (s.orientation_deg, s.insertion_mm) == (pose["orientation_deg"], pose["insertion_mm"])
    bad = {"simulate_tool": {**params["simulate_tool"], "tools_used": ["hammer"]}, "seed": SEED}
    with pytest.raises(ConfigError, match="hammer"):
        ts.session_plan(bad)


def test_calibration_is_plausible_and_round_trips(tmp_path, params):
    C = ts.calibration_matrix(params)
    off = np.abs(C - np.diag(np.diag(C))).sum(axis=1)
    assert (np.abs(np.diag(C)) > 2 * off).all()                    # diagonal-dominant
    n_per_count = C[2, 2] * LSB_V
    assert 0.03 <= n_per_count <= 0.07                             # ~ the public code's 0.0302
    assert 70.0 / n_per_count >= 0.85 * layout.ADC_COUNTS          # +-35 N spans most of 10 bits
    ts.write_session_calibration(tmp_path, params)
    np.testing.assert_allclose(layout.read_calibration(tmp_path / "nano17.cal"), C, rtol=1e-7)
    other = ts.calibration_matrix({**params, "seed": SEED + 1})
    assert not np.allclose(C, other)


# --- determinism and the rig's layout -----------------------------------------------------------

def test_same_seed_gives_byte_identical_files_and_another_seed_does_not(written, normal_spec):
    a, b, c = (_files(written[k]) for k in "abc")
    assert a.keys() == b.keys() == c.keys()
    assert a == b
    trial = normal_spec.name
    assert a[f"{trial}/force.log"] != c[f"{trial}/force.log"]
    assert a[f"{trial}/digit_left/frame_000010.png"] != c[f"{trial}/digit_left/frame_000010.png"]
    assert a["nano17.cal"] != c["nano17.cal"]


def test_rewriting_a_trial_with_fewer_frames_leaves_no_old_frames(tmp_path, normal_spec, params):
    n = params["simulate_tool"]["frames_per_trial"]
    shorter = {**params, "simulate_tool": {**params["simulate_tool"], "frames_per_trial": n // 2}}
    ts.write_trial(tmp_path, normal_spec, params)
    ts.write_trial(tmp_path, normal_spec, shorter)
    for sensor in layout.SENSORS:
        names = sorted(q.name for q in (tmp_path / normal_spec.name / sensor).glob("*.png"))
        assert names == [layout.FRAME_NAME.format(i) for i in range(n // 2)]


def test_written_trial_follows_the_layout(written, normal_spec, params):
    tdir = written["a"] / normal_spec.name
    n = params["simulate_tool"]["frames_per_trial"]
    meta = layout.TrialMeta.read(tdir)
    assert (meta.trial, meta.tool, meta.kind) == (normal_spec.name, normal_spec.tool, "normal")
    assert (meta.orientation_deg, meta.insertion_mm) == (normal_spec.orientation_deg, normal_spec.insertion_mm)
    raw_meta = json.loads((tdir / "meta.json").read_text())
    assert set(raw_meta) == set(layout.TrialMeta.__dataclass_fields__)
    assert "force" not in json.dumps(raw_meta).lower()             # no ground truth beyond the rig's
    for sensor in layout.SENSORS:
        stamps = layout.read_frame_index(tdir / sensor)
        assert len(stamps) == n
        period_ms = np.diff(stamps) / 1e6
        assert abs(period_ms.mean() - 1000 / 30) < 0.3               # 30 fps
        assert period_ms.min() > 20 and period_ms.max() < 47
        assert len(list((tdir / sensor).glob("frame_*.png"))) == n
        img = cv2.imread(str(tdir / sensor / layout.FRAME_NAME.format(n - 1)), cv2.IMREAD_UNCHANGED)
        assert img.dtype == np.uint8 and img.shape == (layout.FRAME_H, layout.FRAME_W, 3)
    lines = (tdir / "force.log").read_text().splitlines()
    assert layout.SERIAL_HEADER.match(lines[0])
    ms = np.array([int(ln.split(",")[0]) for ln in lines[1:]])
    assert (np.diff(ms) > 0).all() and abs(np.median(np.diff(ms)) - 1000 / 15) < 2
    assert all(len(ln.split(",")) == 7 for ln in lines[1:])


def test_frames_are_stamped_at_30fps_from_the_host_clock(sim_normal):
    for sensor in layout.SENSORS:
        t = sim_normal["host_ns"][sensor]
        assert t.dtype == np.int64 and (np.diff(t) > 0).all()
        assert abs(np.median(np.diff(t)) / 1e6 - 1000 / 30) < 2
    first = [sim_normal["host_ns"][s][0] for s in layout.SENSORS]
    assert first[0] != first[1]                                     # two unsynchronised cameras


# --- the Arduino log ----------------------------------------------------------------------------

def _parse_log(lines: list[str], C: np.ndarray, n_bias: int = 5):
    start = int(layout.SERIAL_HEADER.match(lines[0]).group(1))
    rows = np.array([[int(v) for v in ln.split(",")] for ln in lines[1:]])
    volts = layout.counts_to_volts(rows[:, 1:])
    wrench = (volts - volts[:n_bias].mean(axis=0)) @ C.T
    return start, rows[:, 0], wrench


def test_force_log_parses_back_to_the_true_force(normal_spec, params, tmp_path):
    rec = ts.simulate_trial(normal_spec, params, quiet=True)
    ts.write_session_calibration(tmp_path, params)
    C = layout.read_calibration(tmp_path / "nano17.cal")
    ser = rec["serial"]
    start, ms, wrench = _parse_log(rec["serial_lines"], C)
    assert start == ser["start_host_ns"] and 0.05 <= ser["offset_s"] <= 0.5 and ser["clipped"] == 0
    # host time of each line from the known clock offset and rate error
    host = start + ser["offset_s"] * 1e9 + ms * 1e6 / (1 + ser["rate_ppm"] * 1e-6)
    np.testing.assert_allclose(host, ser["stamp_host_ns"], atol=1.0)
    truth_t, truth = rec["truth"]["host_ns"], rec["truth"]["wrench"]
    # quiet: the only error is ADC quantisation (sample +-1/2 LSB, bias +-1/2 LSB) through C
    at_sample = np.column_stack([np.interp(ser["sample_host_ns"], truth_t, truth[:, k]) for k in range(6)])
    bound = np.abs(C).sum(axis=1) * LSB_V + 1e-3
    err = np.abs(wrench - at_sample)
    assert (err <= bound).all(), err.max(axis=0) / bound
    # at the stamps' host times the error adds at most ~1 ms of force change
    at_stamp = np.interp(host, truth_t, truth[:, 2])
    assert np.median(np.abs(wrench[:, 2] - at_stamp)) <= bound[2]
    assert truth[:, 2].min() < -1.0 and truth[:, 2].max() <= 0       # a press reads Fz < 0 (ATI frame)
    inverted = {**params, "simulate_tool": deep_merge(params["simulate_tool"], {"nano17": {"mount": "inverted"}})}
    flipped = tool_sim.trial_mechanics(normal_spec, inverted)["frame_wrench"]["digit_left"]
    upright = tool_sim.trial_mechanics(normal_spec, params)["frame_wrench"]["digit_left"]
    np.testing.assert_allclose(flipped[:, [0, 2]], upright[:, [0, 2]] * [1, -1])
    # with the rig's noise and jitter, still about one count on Fz
    noisy = ts.simulate_trial(normal_spec, params)
    _, _, w = _parse_log(noisy["serial_lines"], C)
    at = np.interp(noisy["serial"]["sample_host_ns"], noisy["truth"]["host_ns"], noisy["truth"]["wrench"][:, 2])
    assert np.median(np.abs(w[:, 2] - at)) < 2 * C[2, 2] * LSB_V


# --- physics in the frames ----------------------------------------------------------------------

def test_imprint_grows_monotonically_with_tip_force(params, default_params):
    forces = [0, 2, 5, 10, 15, 20, 25, 30]
    for spec in (ts.session_plan(params)[0], _spec_for(default_params, "screwdriver_2", 1),
                 _spec_for(default_params, "spatula", 2)):
        out = tool_sim.render_at_forces(spec, default_params, forces)
        for sensor in layout.SENSORS:
            change = _contact_change(out, sensor)
            assert change[0] == 0 and (np.diff(change) > 0).all(), (spec.name, sensor, change)
            assert change[-1] > 10


def test_the_two_fingers_differ_and_the_difference_depends_on_the_pose(default_params):
    asym = {}
    for pose in (0, 1, 2):
        spec = _spec_for(default_params, "screwdriver_1", pose)
        out = tool_sim.render_at_forces(spec, default_params, [0.0, 20.0])
        depth = out["pads"]["depth"][1]                               # (2 pads, samples) mm at 20 N
        assert np.abs(depth[0] - depth[1]).max() > 0.2                 # centre-of-pressure shifts differ
        shear = out["pads"]["dz"][1]
        assert np.abs(shear[0] - shear[1]).max() > 0.05                # differential shear (mm)
        left, right = (_contact_change(out, s)[1] for s in layout.SENSORS)
        asym[pose] = (left - right) / (left + right)
        assert abs(asym[pose]) > 0.05
        # not a mirror image of each other
        diff_l = np.abs(out["digit_left"][1].astype(int) - out["digit_left"][0]).sum(-1)
        diff_r = np.abs(out["digit_right"][1].astype(int) - out["digit_right"][0]).sum(-1)
        assert np.abs(diff_l - diff_r[:, ::-1]).mean() > 0.2 * diff_l.mean()
    assert max(asym.values()) - min(asym.values()) > 0.2


def test_imprint_depth_saturates_near_h_max(default_params):
    cfg = default_params["simulate_tool"]["render"]
    grid = dr.Grid(cfg["px_per_mm"], cfg["height_downsample"])
    s_k = np.linspace(-5, 30, 12)
    contact = dr.LineContact(grid, False, (0.0, 12.0), (0.0, -1.0), s_k, dr.HandleProfile(6.0),
                             0.0, np.random.default_rng(0))
    look = dr.make_look(np.random.default_rng(1), cfg, grid)
    renderer = dr.Renderer(look, grid, cfg, np.random.default_rng(2))
    depths = [0.3, 0.6, 1.2, 2.4, 4.8, 9.6]
    peak = np.array([renderer.gel_height(contact.height(np.full(12, d))).max() for d in depths])
    h_max = cfg["h_max_mm"]
    assert (np.diff(peak) > 0).all() and (peak < h_max).all()
    gain = np.diff(peak) / np.diff(depths)
    assert (np.diff(gain) < 0).all() and gain[-1] < 0.01              # ever smaller gains
    assert peak[-1] > 0.97 * h_max and peak[-1] - peak[-2] < 0.05 * h_max
    assert peak[0] == pytest.approx(0.3, rel=0.1)                     # linear at small depths


def test_reference_frame_already_shows_the_grasp(params, normal_spec):
    out = tool_sim.render_at_forces(normal_spec, params, [0.0])
    for pad, sensor in enumerate(layout.SENSORS):
        ref = out[sensor][0].astype(np.int16)
        blank = out["no_grasp"][sensor].astype(np.int16)
        change = np.abs(ref - blank).sum(-1)
        assert change.max() > 60 and (change > 10).mean() > 0.1         # the preload imprint
        assert out["pads"]["depth"][0, pad].mean() > 0.4                 # mm
        assert out["pads"]["dz"][0, pad].mean() < -0.005                 # the weight pulls the gel down
    # a lighter tool shears the gel less in the reference frame
    light = {**params, "simulate_tool": deep_merge(params["simulate_tool"],
                                                   {"tools": {normal_spec.tool: {"mass_g": 1.0}}})}
    out_light = tool_sim.render_at_forces(normal_spec, light, [0.0])
    assert abs(out_light["pads"]["dz"][0].mean()) < abs(out["pads"]["dz"][0].mean()) / 5


def test_frames_look_like_a_digit(sim_normal):
    # drawn on the real DIGIT frame: darker, red along the left side, green along the right
    for sensor in layout.SENSORS:
        frames = sim_normal["frames"][sensor]
        assert frames.dtype == np.uint8 and frames.shape[1:] == (layout.FRAME_H, layout.FRAME_W, 3)
        ref = frames[0].astype(np.float32)
        assert 85 < ref.mean() < 115
        left, right = ref[60:240, :60].mean(axis=(0, 1)), ref[60:240, -60:].mean(axis=(0, 1))
        assert left[2] > right[2] + 40 and right[1] > right[2] + 20       # red left, green right
        corner = (frames[1].astype(np.float32) - frames[0])[:40, :40]    # no contact there
        assert 0.4 < corner.std() < 3.0                                    # sqrt(2) x sigma 0.3-1 DN
        assert not np.array_equal(frames[0], frames[1])
    # the two fingers are different units: not pixel-identical where nothing touches them
    a, b = (sim_normal["frames"][s][0, :40, :40].astype(np.float32) for s in layout.SENSORS)
    assert np.abs(a - b).mean() > 2.0


def test_normal_trials_keep_the_pads_stuck_and_forces_skewed(default_params):
    forces = []
    for spec in ts.session_plan(default_params):
        mech = tool_sim.trial_mechanics(spec, default_params)
        if spec.kind == "normal":
            assert mech["max_traction_ratio"] < 1.0, spec.name
            fz = -mech["frame_wrench"]["digit_left"][:, 2]          # upright mount: press = -Fz
            assert fz[0] == 0.0                                            # the reference frame is at 0 N
            forces.append(fz)
    f = np.concatenate(forces)
    assert f.max() <= 30.5 and f.min() >= 0
    assert (f < 5).mean() > 0.5 and np.median(f) < f.mean()              # most frames at low force
    assert (f > 15).mean() > 0.03                                        # but the high range is covered


def test_shear_trials_slide_the_tip_under_load(params):
    spec = next(s for s in ts.session_plan(params) if s.kind == "shear")
    mech = tool_sim.trial_mechanics(spec, params)
    w = mech["frame_wrench"]["digit_left"]
    fs, fn = np.hypot(w[:, 0], w[:, 1]), -w[:, 2]
    assert fs.max() > 1.0 and fn.max() > 2.0
    mu_max = params["simulate_tool"]["slide"]["tip_friction"][1]
    assert (fs <= mu_max * fn + 1e-9).all()                              # Coulomb friction bound
    assert fs[0] == 0.0


def test_sliding_tip_is_pinned_by_static_friction_when_it_stands_still(default_params):
    """Loaded but not moving (before the first stroke, between strokes), the tip's reaction is the
    static pin of a press; sliding fast, it is kinetic friction against the velocity."""
    spec = next(s for s in ts.session_plan(default_params) if s.kind == "shear")
    trial = ts.Trial(spec, default_params, noise=False)
    tau = np.linspace(0, trial.duration, 2000)
    reaction = trial.reaction(tau)
    _, vel = trial.profile.tip_motion(tau)
    speed = np.linalg.norm(vel, axis=1)
    normal = reaction[:, 2]
    still = (speed == 0) & (normal > 1.0)
    assert still.sum() > 50
    pinned = trial.grasp.pinned_reaction(normal[still], trial.mu_tip)[:, :2]
    np.testing.assert_allclose(reaction[still, :2], pinned, atol=1e-12)
    assert np.hypot(*pinned.T).min() > 0.0                                  # a tilted tool pushes sideways
    fast = speed > 3 * trial.profile.v0                                    # tanh(3): 99.5 % slipping
    assert fast.sum() > 20
    lat = reaction[fast, :2]
    along = -(lat * vel[fast]).sum(axis=1) / speed[fast]                 # friction opposes the motion
    np.testing.assert_allclose(along, trial.mu_tip * normal[fast], rtol=0.01)
    assert (np.hypot(*reaction[:, :2].T) <= trial.mu_tip * normal + 1e-9).all()


# --- public dataset layout ----------------------------------------------------------------------

def _smooth_frames(n: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    base = cv2.GaussianBlur(rng.uniform(60, 200, (320, 240, 3)).astype(np.float32), (0, 0), 12)
    return [np.clip(base + 3 * i, 0, 255).astype(np.uint8) for i in range(n)]


def test_public_layout_round_trip_normal(tmp_path):
    left, right = _smooth_frames(14, 0), _smooth_frames(14, 1)
    force = np.array([0.0, 0.2, 1.0, 3.3, 7.77, 12.5, 20.0, 29.0, -0.5, 0.05, 5.0, 10.0, -2.0, 15.0])
    tdir = public_formats.write_public_trial(tmp_path, "t01", left, right, force, "normal")
    assert tdir == tmp_path / "data_normal" / "t01"
    assert (tdir / "tactile1" / "tactile_frame_0000.jpg").exists()
    line = (tdir / "force" / "force_data_0000.txt").read_text().strip()
    assert int(line.split(",")[-1]) == 968                               # ~968 at 0 N
    out = pl.read_public_trial(tdir, "normal")
    keep = pl.normal_from_raw(public_formats.raw_from_normal(force)) >= 0
    assert out["dropped"] == int((~keep).sum()) >= 3                     # -0.5, -2.0 and 0 N (raw 968)
    np.testing.assert_array_equal(out["index"], np.flatnonzero(keep))
    assert np.abs(out["force_n"] - force[keep]).max() <= 0.0302 / 2 + 1e-9
    assert np.abs(out["reference_left"].astype(int) - left[0]).mean() < 2.0    # frame 0 (0 N, dropped)
    for got, want in zip(out["frames_left"], [left[i] for i in np.flatnonzero(keep)]):
        assert got.shape == want.shape and np.abs(got.astype(int) - want).mean() < 2.0
    for got, want in zip(out["frames_right"], [right[i] for i in np.flatnonzero(keep)]):
        assert np.abs(got.astype(int) - want).mean() < 2.0


def test_public_layout_round_trip_shear(tmp_path):
    n = 25
    t = np.linspace(0, 3, n)
    forces = np.column_stack([2 * np.sin(t), np.cos(2 * t), -5 - t])
    tdir = public_formats.write_public_trial(tmp_path, "s01", _smooth_frames(n, 2), _smooth_frames(n, 3), forces, "shear")
    assert tdir == tmp_path / "data_shear" / "s01"
    out = pl.read_public_trial(tdir, "shear")
    assert out["dropped"] == 0 and len(out["frames_left"]) == n
    from scipy.signal import savgol_filter
    want = savgol_filter(np.hypot(forces[:, 0], forces[:, 1]), 11, 2)
    np.testing.assert_allclose(out["force_n"], want, atol=2e-4)


def test_simulated_public_session_reads_back(tmp_path, params):
    names = tool_sim.simulate_public_session(tmp_path, params, n_trials=2)
    assert names == ["screwdriver_1_p00_normal00", "screwdriver_1_p00_shear00"]
    n = params["simulate_tool"]["frames_per_trial"] // params["simulate_tool"]["public"]["frame_stride"]
    normal = pl.read_public_trial(tmp_path / "data_normal" / names[0], "normal")
    shear = pl.read_public_trial(tmp_path / "data_shear" / names[1], "shear")
    assert len(normal["frames_left"]) + normal["dropped"] == n and normal["force_n"].max() > 0.5
    assert (normal["force_n"] >= 0).all() and normal["dropped"] > 0      # rest frames around 0 N
    n_shear = params["simulate_tool"]["shear_frames_per_trial"] // params["simulate_tool"]["public"]["frame_stride"]
    assert len(shear["frames_right"]) == n_shear and shear["force_n"].max() > 0.5
    assert normal["frames_left"][0].shape == (layout.FRAME_H, layout.FRAME_W, 3)
    assert normal["reference_left"].shape == (layout.FRAME_H, layout.FRAME_W, 3)   # frame 0, even if dropped
    # the same seed writes the same dataset
    again = tmp_path / "again"
    tool_sim.simulate_public_session(again, params, n_trials=1)
    a, b = tmp_path / "data_normal" / names[0], again / "data_normal" / names[0]
    assert _files(a) == _files(b)


@pytest.fixture
def public_trial(tmp_path) -> Path:
    return public_formats.write_public_trial(tmp_path, "t", _smooth_frames(5, 4), _smooth_frames(5, 5),
                                 np.array([1.0, 2.0, 3.0, 4.0, 5.0]), "normal")


def test_public_reader_missing_force_file_names_the_frame(public_trial):
    (public_trial / "force" / "force_data_0003.txt").unlink()
    with pytest.raises(InputError, match="tactile_frame_0003.jpg") as err:
        pl.read_public_trial(public_trial, "normal")
    assert "force_data_0003.txt" in str(err.value)


def test_public_reader_force_file_without_frame(public_trial):
    (public_trial / "tactile2" / "tactile_frame_0001.jpg").unlink()
    with pytest.raises(InputError, match="force_data_0001.txt"):
        pl.read_public_trial(public_trial, "normal")


def test_public_reader_unreadable_jpg(public_trial):
    bad = public_trial / "tactile1" / "tactile_frame_0002.jpg"
    bad.write_bytes(b"not a jpeg at all")
    with pytest.raises(InputError, match="tactile_frame_0002.jpg") as err:
        pl.read_public_trial(public_trial, "normal")
    assert err.value.path == str(bad)


def test_public_reader_non_numeric_last_field(public_trial):
    bad = public_trial / "force" / "force_data_0004.txt"
    bad.write_text("123,abc\n")
    with pytest.raises(InputError, match="not a number") as err:
        pl.read_public_trial(public_trial, "normal")
    assert err.value.path == str(bad)


def test_public_reader_missing_folder_and_bad_shear_line(public_trial, tmp_path):
    import shutil
    shutil.rmtree(public_trial / "tactile2")
    with pytest.raises(InputError, match="tactile2"):
        pl.read_public_trial(public_trial, "normal")
    tdir = public_formats.write_public_trial(tmp_path, "s", _smooth_frames(3, 6), _smooth_frames(3, 7),
                                 np.ones((3, 3)), "shear")
    (tdir / "force" / "force_data_0001.txt").write_text("1.0,2.0\n")
    with pytest.raises(InputError, match="fx,fy,fz"):
        pl.read_public_trial(tdir, "shear")


def test_sliding_strokes_go_back_and_forth_along_the_axis(default_params):
    slide = default_params["simulate_tool"]["slide"]
    spread = slide["stroke_spread_deg"]
    counts = []
    for spec in [s for s in ts.session_plan(default_params) if s.kind == "shear"][:12]:
        strokes = ts.Trial(spec, default_params, noise=False).profile.strokes
        counts.append(len(strokes))
        deltas = np.array([d for _, _, d in strokes])
        ang = np.rad2deg(np.arctan2(deltas[:, 1], deltas[:, 0])) - slide["stroke_axis_deg"]
        off_axis = np.abs((ang + 90) % 180 - 90)                       # angle to the axis, either way
        assert (off_axis < 4 * spread).all(), spec.name
        assert ((deltas[1:] * deltas[:-1]).sum(axis=1) < 0).all(), spec.name   # each stroke turns back
    assert min(counts) >= 1 and np.mean(counts) > 1.75               # mostly out and back in one grasp


def test_a_force_far_beyond_the_sensor_range_is_dropped_and_counted_at_ingest(tmp_path, smoke_params):
    from tactilepipe.tool.data.ingest import BEYOND_RANGE, ingest_trial
    from tactilepipe.tool.formats.trials import open_trial
    n = 12
    force = np.concatenate([[0.0], np.linspace(1, 12, n - 1)])
    tdir = public_formats.write_public_trial(tmp_path, "t", _smooth_frames(n, 4), _smooth_frames(n, 5), force, "normal")
    (tdir / "force" / "force_data_0005.txt").write_text("5,-1000000\n")     # a garbled count: 30,229 N
    (tmp_path / "trials.csv").write_text("trial,tool,orientation_deg,insertion_mm\nt,knife,5,10\n")
    raw = open_trial(tdir, "public")
    assert np.abs(raw.force_n).max() > 30000                    # what the public conversion makes of it
    info = ingest_trial(raw, tmp_path / "s.parquet", 32, smoke_params["tool_ingest"])
    assert info["drops"][BEYOND_RANGE] == 1 and info["force_samples"] == len(raw.force_n) - 1
    import pandas as pd
    assert pd.read_parquet(tmp_path / "s.parquet")["fz"].abs().max() < 25
    for i in range(n):                                          # every sample garbled: refused, naming the trial
        (tdir / "force" / f"force_data_{i:04d}.txt").write_text(f"{i},-1000000\n")
    with pytest.raises(InputError, match=r"every force sample lies beyond twice the Nano17's rated range"):
        ingest_trial(open_trial(tdir, "public"), tmp_path / "s2.parquet", 32, smoke_params["tool_ingest"])


def test_a_whole_jpeg_with_corrupt_data_is_refused_naming_the_frame(public_trial):
    from tactilepipe.tool.formats.imagefile import read_image
    path = public_trial / "tactile1" / "tactile_frame_0002.jpg"
    data = bytearray(path.read_bytes())
    for k in range(len(data) // 3, len(data) // 3 + 60):       # scramble entropy-coded bytes, keep the end marker
        data[k] ^= 0x5A
    path.write_bytes(bytes(data))
    with pytest.raises(InputError, match=r"tactile_frame_0002.jpg: corrupt image data: the decoder warned 'Corrupt JPEG"):
        read_image(path)
    with pytest.raises(InputError, match=r"tactile_frame_0002.jpg: corrupt image data"):
        pl.read_public_trial(public_trial, "normal")


def test_padding_before_the_jpeg_end_marker_is_not_corruption(tmp_path):
    from tactilepipe.tool.formats.imagefile import read_image
    ok, buf = cv2.imencode(".jpg", _smooth_frames(1, 9)[0])
    data = buf.tobytes()
    path = tmp_path / "padded.jpg"
    path.write_bytes(data[:-2] + b"\x00\x00" + data[-2:])        # what UVC/MJPEG cameras write
    img = read_image(path)
    assert np.array_equal(img, cv2.imdecode(buf, cv2.IMREAD_UNCHANGED))
