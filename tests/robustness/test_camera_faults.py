"""Faults of the rig's cameras in simulated native trials, through the real CLI (tool-ingest,
tool-dataset): frames the camera dropped (frames.csv skips their numbers) are counted and the
trial kept; one camera's frames given for both fingers are refused, naming the cause."""

from __future__ import annotations

import json
import shutil
import subprocess

import numpy as np
import pytest

from support import witness_faults as fault
from support.label_harness import cli
from support.project import REPO
from support.tool_sim import write_session
from tactilepipe.core.config import load_params
from tactilepipe.tool.data.devices import one_camera_twice
from tactilepipe.tool.data.ingest import ingest_trial, preprocess
from tactilepipe.tool.formats.trials import open_trial

# the session of tests/robustness/test_witness.py: one pose, four pressing trials of 72 frames
OVERRIDE = {"tool_ingest": {"stored_size": 32},
            "simulate_tool": {"tools_used": ["screwdriver_1"], "poses_per_tool": 1, "normal_trials_per_pose": 4,
                              "shear_trials_per_pose": 0, "frames_per_trial": 72,
                              "poses": [{"orientation_deg": 12.0, "insertion_mm": 10.0, "lean_deg": -5.0,
                                         "lateral_mm": 1.2}]}}
P = load_params(REPO / "params.yaml", {"scale": "default", **OVERRIDE})
CLI_PARAMS = ["--params", str(REPO / "params.yaml"), "--scale", "default", "--override", json.dumps(OVERRIDE)]
SIZE = P["tool_ingest"]["stored_size"]


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """The session (raw/lab), each trial's clean shard, and which trials the clock aligns."""
    root = tmp_path_factory.mktemp("cameras")
    session = root / "raw" / "lab"
    plan = write_session(session, P)
    shards, aligned = {}, []
    for spec in plan:
        shards[spec.name] = root / "shards" / f"{spec.name}.parquet"
        info = ingest_trial(open_trial(session / spec.name, "native"), shards[spec.name], SIZE, P["tool_ingest"])
        if not info["clock"].get("dropped"):
            aligned.append(spec.name)
    assert aligned
    return {"session": session, "shards": shards, "aligned": aligned}


def _copy(lab, tmp_path):
    name = lab["aligned"][0]
    return name, fault.copy_trial(lab["session"], name, tmp_path / "raw" / "lab")


def _ingest(trial, shard) -> subprocess.CompletedProcess:
    return cli("tool-ingest", *CLI_PARAMS, str(trial), "--format", "native", "--out", str(shard))


def _refused_in_one_line(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode != 0 and "Traceback" not in proc.stderr, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    return proc.stderr


def test_a_burst_of_16_frames_the_camera_dropped_is_counted_and_the_trial_kept(lab, tmp_path):
    name, trial = _copy(lab, tmp_path)
    sensor = trial / "digit_left"
    lines = (sensor / "frames.csv").read_text().splitlines()
    burst = range(30, 46)
    (sensor / "frames.csv").write_text("\n".join([lines[0], *(ln for ln in lines[1:]
                                                              if int(ln.split(",")[0]) not in burst)]) + "\n")
    for n in burst:
        (sensor / f"frame_{n:06d}.png").unlink()
    shard = tmp_path / "t.parquet"
    proc = _ingest(trial, shard)
    assert proc.returncode == 0, proc.stderr
    info = json.loads(proc.stdout)
    assert info["drops"]["digit_left: frames skipped by the camera"] == 16
    assert info["frames"] == {"digit_left": 72 - 16, "digit_right": 72}
    assert "dropped" not in info["clock"], info["clock"]
    shards = [shard] + [s for n, s in lab["shards"].items() if n != name]
    proc = cli("tool-dataset", *CLI_PARAMS, "--kind", "normal", "--shards", *map(str, shards),
               "--out-dir", str(tmp_path / "data"))
    assert proc.returncode == 0, proc.stderr
    qc = json.loads((tmp_path / "data" / "qc.json").read_text())
    kept = {t["trial"]: t for t in qc["trials"]}
    assert kept[f"lab/{name}"]["drops"]["digit_left: frames skipped by the camera"] == 16, qc["dropped_trials"]


def test_one_cameras_folder_copied_over_the_other_finger_is_refused(lab, tmp_path):
    _, trial = _copy(lab, tmp_path)
    shutil.rmtree(trial / "digit_right")
    shutil.copytree(trial / "digit_left", trial / "digit_right")
    message = _refused_in_one_line(_ingest(trial, tmp_path / "t.parquet"))
    assert "digit_left and digit_right hold one camera's frames (72 of 72 frames.csv stamps are the same and " \
           "72 of 72 frame files are byte-identical)" in message and str(trial) in message
    assert not (tmp_path / "t.parquet").exists()


def test_one_cameras_stamps_given_for_both_fingers_are_refused(lab, tmp_path):
    _, trial = _copy(lab, tmp_path)
    shutil.copy(trial / "digit_left" / "frames.csv", trial / "digit_right" / "frames.csv")
    message = _refused_in_one_line(_ingest(trial, tmp_path / "t.parquet"))
    assert "hold one camera's frames (72 of 72 frames.csv stamps are the same)" in message


def test_one_cameras_alternate_frames_as_two_fingers_show_one_view(lab):
    """What only the pixels show: each finger got every other frame of one camera."""
    for name in lab["shards"]:                                                 # two DIGITs, every trial
        raw = open_trial(lab["session"] / name, "native")
        grays = {s: np.stack([preprocess(f.load(i), SIZE) for i in range(len(f))]) for s, f in raw.frames.items()}
        assert one_camera_twice(raw.frames, grays) is None, name
    left = raw.frames["digit_left"]
    alternate = {"digit_left": type(left)(left.host_ns[0::2], left.load, left.source[0::2]),
                 "digit_right": type(left)(left.host_ns[1::2], left.load, left.source[1::2])}
    halves = {"digit_left": grays["digit_left"][0::2], "digit_right": grays["digit_left"][1::2]}
    cause = one_camera_twice(alternate, halves)
    assert cause and cause.startswith("digit_left and digit_right show one camera's view"), cause
    same = {"digit_left": grays["digit_left"], "digit_right": grays["digit_left"]}
    assert "differ by 0.00 gray levels" in one_camera_twice({"digit_left": left, "digit_right": left}, same)
