"""Tool-scene data stages on synthetic inputs: serial log, clock sync, pairing, splits, loader."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from tactilepipe.core.errors import InputError
from tactilepipe.tool.formats.serial_log import read_serial_log
from tactilepipe.tool.data.splits import make_split, parse_split_name, split_name, thin_training
from tactilepipe.tool.data.clock_sync import fit_offset
from tactilepipe.tool.data.sync import interpolate_at, pair_frames
from tactilepipe.tool.formats.native_layout import calibrate


def write_log(path, lines, header="# start_host_ns=1000000000", newline_at_end=True):
    text = "\n".join([header] + lines) + ("\n" if newline_at_end else "")
    path.write_bytes(text.encode("latin-1"))
    return path


def good_lines(n=50, start_ms=100, step=67):
    return [f"{start_ms + i * step},512,512,{512 + i % 7},512,512,512" for i in range(n)]


# --- serial log ---------------------------------------------------------------------------------

def test_serial_log_parses_a_clean_log(tmp_path):
    log = read_serial_log(write_log(tmp_path / "force.log", good_lines()))
    assert log.start_host_ns == 1_000_000_000
    assert log.arduino_ms[0] == 100 and np.all(np.diff(log.arduino_ms) == 67)
    assert log.counts.shape == (50, 6) and not log.drops


def test_serial_log_counts_garbled_lines_instead_of_failing(tmp_path):
    lines = good_lines()
    lines.insert(0, "5,512,51")                    # partial first line when the port opened
    lines.insert(10, "\xff\xfe\x00garbage")          # corrupted bytes
    lines.insert(20, "1500,512,512,abc,512,512,512")  # non-numeric value
    lines.insert(30, "2500,512,512,512,512,512")      # a column missing
    lines.insert(40, "3000,512,512,512,512,512,5120")  # out of ADC range
    lines.append("9999,51")                           # truncated last line, no newline at the end
    log = read_serial_log(write_log(tmp_path / "f.log", lines, newline_at_end=False))
    assert len(log.arduino_ms) == 50
    assert log.drops["garbage bytes"] == 1
    assert log.drops["non-numeric field"] == 1
    assert log.drops["wrong column count"] == 2
    assert log.drops["ADC count out of range"] == 1
    assert log.drops["truncated last line"] == 1


@pytest.mark.parametrize("lines, header, needle", [
    (good_lines(), "start", "first line must be"),
    ([f"{t},1,1,1,1,1,1" for t in (100, 200, 150, 250)] + good_lines(10, 300), None, "jumps back from 200 to 150"),
    (["100,1,1,1,1,1,1", "100,1,1,1,1,1,1"] + good_lines(10, 200), None, "duplicated Arduino timestamp"),
    (["x"] * 10 + good_lines(5), None, "unreadable"),
])
def test_serial_log_errors_name_the_file_and_line(tmp_path, lines, header, needle):
    path = write_log(tmp_path / "force.log", lines, header or "# start_host_ns=5")
    with pytest.raises(InputError) as err:
        read_serial_log(path)
    assert needle in str(err.value) and "force.log" in str(err.value)


def test_serial_clock_jump_names_the_line(tmp_path):
    lines = good_lines(5) + ["10,512,512,512,512,512,512"]
    with pytest.raises(InputError, match=r"\[line 7\]"):
        read_serial_log(write_log(tmp_path / "force.log", lines))


# --- calibration and clock sync ------------------------------------------------------------------

def test_calibration_applies_matrix_to_bias_removed_volts():
    matrix = np.diag([10.0, 20.0, 30.0, 1.0, 1.0, 1.0])
    counts = np.array([[512, 512, 512, 512, 512, 512], [612, 512, 712, 512, 512, 512]])
    f = calibrate(counts, matrix, counts[0])
    assert np.allclose(f[0], 0.0)
    volt = 5.0 / 1023
    assert f[1, 0] == pytest.approx(100 * volt * 10.0) and f[1, 2] == pytest.approx(200 * volt * 30.0)


@pytest.mark.parametrize("true_offset", [-0.35, -0.12, 0.0, 0.083, 0.41])
def test_offset_is_recovered_from_tactile_and_force_signals(true_offset):
    rng = np.random.default_rng(3)
    frame_t = np.arange(0, 20, 1 / 30)
    presses = lambda t: np.clip(np.sin(2 * np.pi * t / 5.0 + 0.3 * np.sin(t)), 0, None) ** 1.5 * 20
    tactile = presses(frame_t) * 1.7 + rng.normal(0, 0.3, len(frame_t))
    force_t = np.arange(0, 20, 1 / 15) + rng.normal(0, 0.003, 300)       # 15 Hz with jitter
    force = presses(force_t) + rng.normal(0, 0.05, len(force_t))
    fit = fit_offset({"digit_left": (frame_t, tactile)}, force_t - true_offset, force, search_s=1.0)
    assert fit.shift_s == pytest.approx(true_offset, abs=0.01)
    assert fit.score > 0.9 and not fit.on_edge


def test_interpolation_drops_frames_across_force_gaps():
    sample_t = np.array([0.0, 1.0, 2.0, 5.0, 6.0])
    values = np.column_stack([sample_t * 2])
    out, ok = interpolate_at(np.array([0.5, 1.5, 3.0, 5.5, 7.0, -1.0, 6.0]), sample_t, values, max_gap=1.5)
    assert ok.tolist() == [True, True, False, True, False, False, True]
    assert out[ok, 0] == pytest.approx([1.0, 3.0, 11.0, 12.0])


def test_frames_of_the_two_fingers_pair_within_half_a_period():
    left = np.arange(0, 1_000_000_000, 33_333_333)
    right = left[:-3] + 5_000_000                        # 5 ms later, three frames missing
    right = np.delete(right, [10, 11])
    il, ir = pair_frames(left, right, 16_666_666)
    assert len(il) == len(right)
    assert np.all(np.abs(right[ir] - left[il]) <= 16_666_666)
    assert len(np.unique(ir)) == len(ir)


# --- splits --------------------------------------------------------------------------------------

@pytest.fixture
def samples():
    rows = []
    for tool in ("screwdriver_1", "screwdriver_2", "paper_knife", "spatula"):
        for pose in range(3):
            for trial in range(2):
                n = 40 + 5 * pose
                rows.append(pd.DataFrame({"trial": f"s/{tool}_p{pose}_t{trial}", "tool": tool,
                                          "pose": f"{tool}@{pose}", "fz": np.linspace(0, 20 + pose, n)}))
    return pd.concat(rows, ignore_index=True)


@pytest.mark.parametrize("name", ["frame", "trial", "trial_r2", "loto_spatula", "lopo"])
def test_splits_are_disjoint_and_cover_the_data(samples, name):
    split = make_split(samples, name, "fz", seed=1, holdout_pose=0)
    parts = [set(split[k]) for k in ("train", "validation", "test")]
    assert all(parts) and not (parts[0] & parts[1]) and not (parts[0] & parts[2]) and not (parts[1] & parts[2])
    assert set().union(*parts) == set(range(len(samples)))
    train_labels = samples["fz"].to_numpy()[split["train"]]
    assert split["label_stats"]["max"] == pytest.approx(train_labels.max())     # training split only
    assert split["leaky"] == (name == "frame")


def test_trial_split_keeps_whole_trials_together(samples):
    split = make_split(samples, "trial", "fz", seed=1)
    trials = [set(samples["trial"].iloc[split[k]]) for k in ("train", "validation", "test")]
    assert not (trials[0] & trials[1]) and not (trials[0] & trials[2]) and not (trials[1] & trials[2])
    frac = len(split["train"]) / len(samples)
    assert 0.6 < frac < 0.8


def test_trial_split_is_stratified_by_tool(samples):
    # 6 trials per tool: each tool has one test and one validation trial, and four for training
    split = make_split(samples, "trial", "fz", seed=3)
    for k, n in (("train", 4), ("validation", 1), ("test", 1)):
        rows = samples.iloc[split[k]]
        assert rows.groupby("tool")["trial"].nunique().to_dict() == dict.fromkeys(samples["tool"].unique(), n), k
    # with fewer than 3 trials for some tool it cannot be stratified: whole trials, unstratified
    few = samples[~samples["trial"].str.contains("spatula_p[12]")].reset_index(drop=True)
    split = make_split(few, "trial", "fz", seed=3)
    trials = [set(few["trial"].iloc[split[k]]) for k in ("train", "validation", "test")]
    assert all(trials) and not (trials[0] & trials[1]) and not (trials[0] & trials[2]) and not (trials[1] & trials[2])
    assert set().union(*trials) == set(few["trial"])


def test_frame_split_leaks_trials_across_splits(samples):
    split = make_split(samples, "frame", "fz", seed=1)
    train_trials = set(samples["trial"].iloc[split["train"]])
    assert set(samples["trial"].iloc[split["test"]]) <= train_trials      # why it is "leaky"


@pytest.mark.parametrize("tool", ["screwdriver_1", "screwdriver_2", "paper_knife", "spatula"])
def test_leave_one_tool_out_tests_only_the_held_out_tool(samples, tool):
    split = make_split(samples, f"loto_{tool}", "fz", seed=1)
    assert set(samples["tool"].iloc[split["test"]]) == {tool}
    assert tool not in set(samples["tool"].iloc[split["train"] + split["validation"]])
    assert (split["kind"], split["repeat"]) == ("loto", 0)


def test_a_held_out_tool_that_is_not_in_the_data_or_an_unknown_split_is_refused(samples):
    with pytest.raises(InputError, match="held-out tool 'hammer'"):
        make_split(samples, "loto_hammer", "fz", seed=1)
    for name in ("loto", "trial_r0", "trial_rx", "random", "lopo_2"):
        with pytest.raises(InputError, match=f"unknown split '{name}'"):
            make_split(samples, name, "fz", seed=1)


def test_split_names_parse_into_kind_repeat_and_tool():
    assert parse_split_name("trial") == ("trial", 0, None)
    assert parse_split_name("trial_r12") == ("trial", 12, None)
    assert parse_split_name("public_frame_r1") == ("public_frame", 1, None)
    assert parse_split_name("loto_screwdriver_1") == ("loto", 0, "screwdriver_1")
    assert [split_name("trial", k) for k in range(3)] == ["trial", "trial_r1", "trial_r2"]


def test_every_repeat_is_grouped_by_trial_stratified_by_tool_and_drawn_anew(samples):
    splits = [make_split(samples, split_name("trial", k), "fz", seed=1) for k in range(5)]
    assert splits[0] == {**make_split(samples, "trial", "fz", seed=1)}      # repeat 0 is the unsuffixed split
    for k, split in enumerate(splits):
        assert split["repeat"] == k and split["kind"] == "trial"
        trials = [set(samples["trial"].iloc[split[part]]) for part in ("train", "validation", "test")]
        assert not (trials[0] & trials[1]) and not (trials[0] & trials[2]) and not (trials[1] & trials[2])
        for part, n in (("train", 4), ("validation", 1), ("test", 1)):       # 6 trials per tool
            rows = samples.iloc[split[part]]
            assert rows.groupby("tool")["trial"].nunique().to_dict() == dict.fromkeys(samples["tool"].unique(), n)
    tests = [tuple(s["trials"]["test"]) for s in splits]
    assert len(set(tests)) == len(tests)                  # each repeat has its own test trials


def test_leave_one_pose_out_tests_one_pose_of_every_tool(samples):
    split = make_split(samples, "lopo", "fz", seed=1, holdout_pose=2)
    test_poses = set(samples["pose"].iloc[split["test"]])
    assert test_poses == {f"{t}@2" for t in samples["tool"].unique()}
    assert not test_poses & set(samples["pose"].iloc[split["train"]])


def test_splits_are_seeded(samples):
    a, b = make_split(samples, "trial", "fz", seed=1), make_split(samples, "trial", "fz", seed=1)
    c = make_split(samples, "trial", "fz", seed=2)
    assert a["test"] == b["test"] and a["test"] != c["test"]


def test_thin_training_keeps_whole_trials_per_tool_and_leaves_validation_and_test_alone(samples):
    split = make_split(samples, "trial", "fz", seed=3)           # 4 training trials per tool
    half = thin_training(split, samples, seed=5, trial_fraction=0.5)
    rows = samples.iloc[half["train"]]
    assert rows.groupby("tool")["trial"].nunique().to_dict() == dict.fromkeys(samples["tool"].unique(), 2)
    kept = set(rows["trial"])
    assert kept == set(half["trials"]["train"])
    # every frame of a kept trial stays; nothing outside the original training set comes in
    assert len(rows) == samples["trial"].isin(kept).sum()
    assert set(half["train"]) <= set(split["train"])
    assert half["validation"] == split["validation"] and half["test"] == split["test"]
    assert half["label_stats"] == split["label_stats"]
    # nested: a larger fraction keeps the smaller fraction's trials
    three_q = thin_training(split, samples, seed=5, trial_fraction=0.75)
    assert kept < set(three_q["trials"]["train"])


def test_thin_training_by_frame_stride_keeps_every_trial(samples):
    split = make_split(samples, "trial", "fz", seed=3)
    thin = thin_training(split, samples, seed=5, frame_stride=3)
    assert thin["trials"]["train"] == split["trials"]["train"]
    for trial, group in samples.iloc[thin["train"]].groupby("trial"):
        full = samples.index[samples["trial"] == trial]
        assert list(group.index) == list(full[::3])
    with pytest.raises(InputError, match="frame_stride"):
        thin_training(split, samples, seed=5, frame_stride=0)
