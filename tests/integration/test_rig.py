"""`tactilepipe record` and `tactilepipe live` against a stand-in rig made of real parts: the
cameras are OpenCV VideoCaptures over image sequences of a simulated trial (the code path of a
device, only the source string differs), the Arduino a separate process behind a real
pseudo-terminal that pyserial opens (tests/support/standin_rig.py)."""

from __future__ import annotations

import io
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
import torch

from support.tool_data import quick_cfg
from support.standin_rig import GARBAGE, StandInArduino, camera_sequences, write_plan
from support.project import SMOKE, results
from tactilepipe.core.config import load_params
from tactilepipe.rig.cameras import from_layout
from tactilepipe.tool.data.ingest import ingest_trial
from tactilepipe.tool.formats.native_layout import SENSORS, read_frame_index, write_calibration
from tactilepipe.tool.formats.trials import list_trials, open_trial
from tactilepipe.tool.model.checkpoint import CHECKPOINT_FORMAT
from tactilepipe.tool.model.network import build_model
from tactilepipe.tool.model.stream import stream_predictions
from tactilepipe.tool.sim.plan import TrialSpec, calibration_matrix
from tactilepipe.tool.sim.trial import simulate_trial

P = load_params()
FPS = 30.0                      # the simulated DIGITs' rate: the stand-in plays it in mode qvga30
SECONDS = 2.8                   # of the simulated trial's 100 frames (3.3 s)


def _cli(*args: str, stdin: str = "") -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "tactilepipe", *args], capture_output=True, text=True,
                          input=stdin, timeout=120)


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    """A simulated pressing trial as stand-in camera sequences and an Arduino plan."""
    root = tmp_path_factory.mktemp("rig")
    spec = TrialSpec("standin", "screwdriver_1", "normal", 0.0, 20.0, 0)
    sim = simulate_trial(spec, P)
    assert sim["meta"].camera_fps == FPS
    write_plan(sim, root / "plan.npz")
    write_calibration(root / "nano17.cal", calibration_matrix(P))
    return {"root": root, "sim": sim, "sources": camera_sequences(sim, root / "cameras")}


def _record(rig, session: Path, arduino: StandInArduino, *extra: str, sources=None,
            stdin: str = "") -> subprocess.CompletedProcess:
    sources = sources or rig["sources"]
    return _cli("record", "--session", str(session), "--left", sources["digit_left"], "--right",
                sources["digit_right"], "--port", arduino.port, "--mode", "qvga30", "--calibration",
                str(rig["root"] / "nano17.cal"), "--tool", "screwdriver_1", "--kind", "normal",
                "--orientation-deg", "0", "--insertion-mm", "20", *extra, stdin=stdin)


def test_two_recorded_trials_ingest_with_every_drop_explained_and_the_clock_recovered(rig, tmp_path):
    session = tmp_path / "raw" / "tool" / "lab-1"
    with StandInArduino(rig["root"] / "plan.npz", tmp_path / "truth.jsonl") as arduino:
        done = _record(rig, session, arduino, "--seconds", str(SECONDS), "--trials", "2", stdin="\n\n")
        truths = arduino.records()
    assert done.returncode == 0, done.stderr
    assert "fps" in done.stderr and "|F|" in done.stderr            # the progress line
    trials = list_trials(session)
    assert [name for name, _, _ in trials] == ["screwdriver_1_normal_000", "screwdriver_1_normal_001"]
    assert len(truths) == 2
    for (name, path, fmt), truth in zip(trials, truths):
        meta = json.loads((path / "meta.json").read_text())
        rec = meta["notes"]["recorder"]
        for s in SENSORS:
            cam = rec["cameras"][s]
            assert cam["dropped_frames"] == 0 and cam["read_timeouts"] == 0 and not cam["lost"]
            assert cam["frames"] == len(read_frame_index(path / s)) >= int(SECONDS * FPS) - 2
        log = (path / "force.log").read_bytes()
        garbage = sum(log.count(g) for g in GARBAGE)
        # the stop may cut the line being sent: it is logged as it came, without its end, and
        # counted by both the recorder and ingest ("truncated last line")
        cut = 0 if log.endswith(b"\n") else 1
        assert garbage > 0 and sum(rec["serial"]["unparsed_lines"].values()) == garbage + cut, rec["serial"]
        info = ingest_trial(open_trial(path, fmt), tmp_path / f"{name}.parquet", 32, P["tool_ingest"])
        # every drop is one of the garbage lines the stand-in sent, by the parser's reasons, or the cut line
        serial_drops = {k: v for k, v in info["drops"].items() if k.startswith("serial")}
        assert sum(serial_drops.values()) == garbage + cut, info["drops"]
        if cut and not any(g.startswith(log.rsplit(b"\n", 1)[1]) for g in GARBAGE):   # (a cut garbage line stays garbage)
            assert serial_drops.get("serial: truncated last line") == 1, info["drops"]
        assert sum(v for k, v in info["drops"].items() if not k.startswith("serial")) == 0, info["drops"]
        # the recorder stamps each serial line on arrival (force_arrival.csv): the Arduino's clock is
        # fitted to those stamps, and puts millis 0 within a few ms of the host time the stand-in's
        # millis() started (its boot after the port's open)
        assert info["clock"]["method"] == "serial_arrival" and "dropped" not in info["clock"], info["clock"]
        start_host_ns = int(log.split(b"\n", 1)[0].split(b"=")[1])
        fitted_ns = start_host_ns + info["clock"]["millis0_after_port_open_s"] * 1e9
        assert abs(fitted_ns - truth["clock_start_ns"]) < 0.01e9, (fitted_ns - truth["clock_start_ns"]) / 1e9


def test_a_trial_that_loses_the_arduino_or_a_camera_is_set_aside(rig, tmp_path):
    session = tmp_path / "raw" / "tool" / "lab-2"
    with StandInArduino(rig["root"] / "plan.npz", tmp_path / "truth.jsonl", unplug_after_s=1.0) as arduino:
        cut = _record(rig, session, arduino, "--seconds", str(SECONDS), "--no-prompt")
    assert cut.returncode == 1
    assert "stopped half-way" in cut.stderr and "serial port closed" in cut.stderr, cut.stderr
    aside = tmp_path / "raw" / "tool" / "incomplete" / "lab-2" / "screwdriver_1_normal_000"
    assert "serial port closed" in json.loads((aside / "meta.json").read_text())["notes"]["incomplete"]
    assert not (session / "screwdriver_1_normal_000").exists()

    short = tmp_path / "short"                   # a camera whose video ends after 20 frames
    for s in SENSORS:
        (short / s).mkdir(parents=True)
        for k in range(20 if s == "digit_right" else 100):
            (short / s / f"frame_{k:06d}.png").write_bytes(
                (Path(rig["sources"][s].replace("%06d", f"{k:06d}"))).read_bytes())
    with StandInArduino(rig["root"] / "plan.npz", tmp_path / "truth2.jsonl") as arduino:
        ended = _record(rig, session, arduino, "--seconds", str(SECONDS), "--no-prompt",
                        sources={s: str(short / s / "frame_%06d.png") for s in SENSORS})
    assert ended.returncode == 1 and "camera digit_right" in ended.stderr and "the file ended" in ended.stderr
    assert list((tmp_path / "raw" / "tool" / "incomplete" / "lab-2").iterdir())
    assert not any(p.name.startswith("screwdriver") for p in session.iterdir())


def _random_checkpoint(path: Path) -> Path:
    """A model whose output moves with its input (a freshly built one predicts a constant: its
    output layer starts at zero)."""
    torch.manual_seed(3)
    model = build_model("full", 18, 16, "sigmoid", 8)
    with torch.no_grad():
        for p in model.parameters():
            if not p.any():
                p.normal_(0, 0.1) if p.dim() > 1 else p.fill_(1.0)
    meta = {"variant": "full", "depth": 18, "image_size": 16, "normalise": "minmax", "width": 8,
            "gam_channel_gate": "sigmoid", "label_stats": {"min": 0.0, "max": 30.0, "mean": 5.0, "std": 5.0}}
    cfg = quick_cfg(image_size=16, width=8).model_dump()
    torch.save({"format": CHECKPOINT_FORMAT, "model": model.state_dict(), "config": cfg, "meta": meta}, path)
    return path


def test_live_on_a_recorded_trial_gives_the_estimates_of_predict(rig, tmp_path):
    session = tmp_path / "raw" / "tool" / "lab-3"
    with StandInArduino(rig["root"] / "plan.npz", tmp_path / "truth.jsonl") as arduino:
        done = _record(rig, session, arduino, "--seconds", "2.0", "--no-prompt")
    assert done.returncode == 0, done.stderr
    trial = session / "screwdriver_1_normal_000"
    ckpt = _random_checkpoint(tmp_path / "model.pt")
    replay = tmp_path / "replay"                 # the recorded frames, played back as the cameras stream
    for s in SENSORS:
        (replay / s).mkdir(parents=True)
        for png in sorted((trial / s).glob("frame_*.png")):
            cv2.imwrite(str(replay / s / png.name), from_layout(cv2.imread(str(png))))
    out = io.StringIO()
    stream_predictions(ckpt, trial, "native", P, out=out)
    rows = [line for line in out.getvalue().splitlines() if not line.startswith("#")]
    predicted = pd.read_csv(io.StringIO("\n".join(rows)))
    live = _cli("live", "--checkpoint", str(ckpt), "--left", str(replay / "digit_left" / "frame_%06d.png"),
                "--right", str(replay / "digit_right" / "frame_%06d.png"), "--mode", "qvga30", "--seconds", "30",
                "--log", str(tmp_path / "live" / "estimates.csv"))
    assert live.returncode == 0, live.stderr
    logged = pd.read_csv(tmp_path / "live" / "estimates.csv")
    both = logged.merge(predicted, on=["left_frame", "right_frame"])
    # every estimate live logged is one of predict's frame pairs; how many it reached depends on
    # this machine's load (it skips frames to keep up), and it says how many it skipped
    per_camera = re.search(r"frames skipped (\{.*?\})", live.stdout).group(1)       # {'digit_left': n, ...}
    skipped = max(int(n) for n in re.findall(r": (\d+)", per_camera))
    assert len(both) == len(logged) >= 10, (len(both), len(logged), len(predicted))
    assert len(logged) + skipped >= len(predicted) - 2, (len(logged), skipped, len(predicted))
    assert both["prediction_n"].std() > 1e-3        # the estimates move with the frames: 100x the tolerance below
    np.testing.assert_allclose(both["estimate_n"], both["prediction_n"], atol=1e-5)
    assert "frames skipped" in live.stdout and "stopped early" in live.stdout     # the replay ended


@pytest.mark.extended
def test_a_recorded_session_runs_through_the_pipeline_with_no_step_by_hand(rig, tmp_path):
    """Trials of two tools recorded from the stand-in, then the tool_normal scene at the smoke
    scale by Snakemake alone: ingest, clock alignment, dataset, splits, every model, the reports."""
    from support.project import copy_project, snakemake
    wd = tmp_path / "project"
    wd.mkdir()
    copy_project(wd, scale="smoke")
    session = wd / "raw" / "tool" / "lab-4"
    with StandInArduino(rig["root"] / "plan.npz", tmp_path / "truth.jsonl") as arduino:
        for tool in ("screwdriver_1", "spatula"):
            done = _cli("record", "--session", str(session), "--left", rig["sources"]["digit_left"], "--right",
                        rig["sources"]["digit_right"], "--port", arduino.port, "--mode", "qvga30", "--calibration",
                        str(rig["root"] / "nano17.cal"), "--tool", tool, "--kind", "normal", "--seconds", "2.5",
                        "--trials", "3", "--no-prompt")
            assert done.returncode == 0, done.stderr
    assert len(list_trials(session)) == 6
    snakemake(wd, f"{SMOKE}/tool_normal/metrics/full.json", f"{SMOKE}/tool_normal/qc.md", "--config",
              'tool_sessions=["lab-4"]', "scenes=[tool_normal]")
    metrics = json.loads((results(wd) / "tool_normal/scores.json").read_text())
    qc = (results(wd) / "tool_normal/qc.md").read_text()
    assert "spatula_normal_002" in qc and "screwdriver_1_normal_000" in qc
    for variant in P["tool_train"]["variants"]:          # resolved: "all" spelled out
        assert np.isfinite(metrics[variant]["mae"]) and metrics[variant]["over_splits"]["mae"]["n"] == 2
    assert metrics["loto"]["over_tools"]["mae"]["n"] == 2                 # each recorded tool left out once


def test_a_port_that_prints_nothing_stops_before_any_trial_is_started(rig, tmp_path):
    import os
    import pty
    master, slave = pty.openpty()                     # a serial port with nothing behind it
    try:
        session = tmp_path / "raw" / "tool" / "lab-5"
        silent = _cli("record", "--session", str(session), "--left", rig["sources"]["digit_left"], "--right",
                      rig["sources"]["digit_right"], "--port", os.ttyname(slave), "--mode", "qvga30",
                      "--calibration", str(rig["root"] / "nano17.cal"), "--tool", "knife", "--kind", "normal",
                      "--seconds", "1", "--no-prompt")
    finally:
        os.close(master)
        os.close(slave)
    assert silent.returncode == 2 and "no sample line within 3 s of opening the port" in silent.stderr, silent.stderr
    assert not (tmp_path / "raw" / "tool" / "incomplete").exists()
    assert not list((tmp_path / "raw" / "tool" / ".recording" / "lab-5").iterdir())


def test_an_arduino_that_ends_lines_with_cr_only_is_recorded_not_hung(rig, tmp_path):
    """pyserial's readline waits for a \\n as long as bytes keep coming: such a board used to hang
    `record` for good (the first-sample timeout fired, then stop() joined the blocked reader)."""
    from tactilepipe.tool.formats.serial_log import read_serial_log
    session = tmp_path / "raw" / "tool" / "lab-cr"
    with StandInArduino(rig["root"] / "plan.npz", tmp_path / "truth.jsonl", garbage_every=0,
                        line_end=b"\r") as arduino:
        done = _record(rig, session, arduino, "--seconds", "1.5", "--no-prompt")
    assert done.returncode == 0, done.stderr
    trial = session / "screwdriver_1_normal_000"
    serial = json.loads((trial / "meta.json").read_text())["notes"]["recorder"]["serial"]
    assert set(serial["line_ends"]) == {"\\r"} and serial["line_ends"]["\\r"] >= 15, serial
    log = read_serial_log(trial / "force.log")           # ingest's parser reads every sample line
    assert len(log.arduino_ms) >= 15 and (np.diff(log.arduino_ms) > 0).all()


def test_an_arduino_that_resets_mid_trial_is_found_while_recording(rig, tmp_path):
    session = tmp_path / "raw" / "tool" / "lab-reset"
    with StandInArduino(rig["root"] / "plan.npz", tmp_path / "truth.jsonl", reset_after_s=0.8) as arduino:
        cut = _record(rig, session, arduino, "--seconds", "10", "--no-prompt")
    assert cut.returncode == 1, cut.stderr
    assert "stopped half-way (the Arduino's clock jumped back from" in cut.stderr and "it reset mid-trial" in cut.stderr
    aside = tmp_path / "raw" / "tool" / "incomplete" / "lab-reset" / "screwdriver_1_normal_000"
    meta = json.loads((aside / "meta.json").read_text())["notes"]
    assert "reset mid-trial" in meta["incomplete"]
    assert meta["recorder"]["seconds_recorded"] < 5                 # stopped when seen, not after 10 s


@pytest.mark.parametrize("flag, name", [("--trial", "../../escaped_trial"), ("--trial", "a/b"), ("--trial", ".."),
                                        ("--session", "raw/tool/../../escaped_session")])
def test_a_trial_or_session_name_that_is_a_path_is_refused(rig, tmp_path, flag, name, capsys, monkeypatch):
    from tactilepipe.cli.main import main
    monkeypatch.chdir(tmp_path)
    session = "raw/tool/lab-3" if flag == "--trial" else name
    extra = [flag, name] if flag == "--trial" else []
    status = main(["record", "--session", session, "--left", rig["sources"]["digit_left"], "--right",
                   rig["sources"]["digit_right"], "--port", "/dev/null", "--calibration", str(rig["root"] / "nano17.cal"),
                   "--tool", "knife", "--kind", "normal", "--seconds", "1", "--no-prompt", *extra])
    err = capsys.readouterr().err
    assert status == 2 and ("a name is letters, digits, _ - and ." in err or "without '..'" in err), err
    assert not any(tmp_path.rglob("escaped*")) and not (tmp_path / "raw").exists()


@pytest.mark.parametrize("value", ["-5", "0", "nan", "inf"])
def test_record_refuses_a_length_that_is_not_positive_and_finite_before_anything_is_written(rig, tmp_path, value,
                                                                                            capsys, monkeypatch):
    from tactilepipe.cli.main import main
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exit_:
        main(["record", "--session", "raw/tool/lab-5", "--left", rig["sources"]["digit_left"], "--right",
              rig["sources"]["digit_right"], "--port", "/dev/null", "--calibration", str(rig["root"] / "nano17.cal"),
              "--tool", "knife", "--kind", "normal", "--seconds", value, "--no-prompt"])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and f"argument --seconds: {value} is not a length: give a finite number of " \
                                      f"seconds above 0" in err.splitlines()[-1], err
    assert not (tmp_path / "raw").exists()


def test_record_refuses_one_camera_for_both_fingers(rig, tmp_path, capsys, monkeypatch):
    from tactilepipe.cli.main import main
    monkeypatch.chdir(tmp_path)
    status = main(["record", "--session", "raw/tool/lab-6", "--left", rig["sources"]["digit_left"], "--right",
                   rig["sources"]["digit_left"], "--port", "/dev/null", "--calibration",
                   str(rig["root"] / "nano17.cal"), "--tool", "knife", "--kind", "normal", "--seconds", "1",
                   "--no-prompt"])
    err = capsys.readouterr().err
    assert status == 2 and "--left and --right are the same camera" in err and len(err.strip().splitlines()) == 1, err
    assert not list((tmp_path / "raw" / "tool" / "lab-6").glob("knife*"))


def _live(rig, tmp_path, *extra: str, sources=None) -> subprocess.CompletedProcess:
    sources = sources or rig["sources"]
    ckpt = tmp_path / "model.pt" if (tmp_path / "model.pt").exists() else _random_checkpoint(tmp_path / "model.pt")
    return _cli("live", "--checkpoint", str(ckpt), "--left", sources["digit_left"], "--right",
                sources["digit_right"], "--mode", "qvga30", "--seconds", "20", "--log",
                str(tmp_path / "live" / "estimates.csv"), *extra)


def _one_line(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    lines = [ln for ln in proc.stderr.strip().splitlines() if not ln.startswith(("keep the fingers", "reference pair"))]
    assert len(lines) == 1, proc.stderr
    return lines[0]


def test_live_refuses_one_camera_for_both_fingers_and_an_inverted_label_range(rig, tmp_path):
    same = _live(rig, tmp_path, sources={s: rig["sources"]["digit_left"] for s in SENSORS})
    assert "--left and --right are the same camera" in _one_line(same)
    inverted = _live(rig, tmp_path, "--label-range", "30", "0")
    assert "--label-range 30 0: give MIN_N then MAX_N, MIN_N below MAX_N" in _one_line(inverted)
    nan = _live(rig, tmp_path, "--label-range", "0", "nan")
    assert nan.returncode == 2 and "argument --label-range: nan is not a finite number" in nan.stderr


def test_live_refuses_a_reference_that_is_not_two_bgr_frames(rig, tmp_path):
    frame = cv2.imread(rig["sources"]["digit_left"] % 0)
    np.savez(tmp_path / "reference.npz", digit_left=frame.astype(np.float64) / 255, digit_right=frame / 255.0)
    line = _one_line(_live(rig, tmp_path, "--reference", str(tmp_path / "reference.npz")))
    assert f"{tmp_path / 'reference.npz'}: digit_left is float64 of shape" in line and "not a BGR uint8 frame" in line


def test_live_stops_on_a_resolution_change_mid_stream_naming_the_camera(rig, tmp_path):
    changed = tmp_path / "changed"
    shutil.copytree(Path(rig["sources"]["digit_right"]).parent, changed)
    for png in sorted(changed.glob("frame_*.png"))[20:]:                 # the stream turns VGA at frame 20
        cv2.imwrite(str(png), cv2.resize(cv2.imread(str(png)), (640, 480)))
    line = _one_line(_live(rig, tmp_path, sources={"digit_left": rig["sources"]["digit_left"],
                                                   "digit_right": str(changed / "frame_%06d.png")}))
    assert re.search(r"digit_right: frame \d+ is 480x640, its reference frame was 240x320: the resolution changed "
                     r"mid-stream", line), line
