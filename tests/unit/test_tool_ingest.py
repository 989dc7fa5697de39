"""Native trial -> shard -> synced dataset, on a hand-built trial with a known clock offset."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from tactilepipe.core.config import load_params
from tactilepipe.core.errors import InputError
from tactilepipe.tool.data.dataset import build_tool_dataset
from tactilepipe.tool.data.ingest import ingest_trial, read_shard_info
from tactilepipe.tool.formats.native_layout import FRAME_H, FRAME_W, TrialMeta, write_calibration
from tactilepipe.tool.data.loader import ToolFrames
from tactilepipe.tool.formats.native_import import read_native_trial

CAL = np.diag([8.0, 8.0, 20.0, 100.0, 100.0, 100.0])   # N/V: 5/1023 V per count -> ~0.1 N per Fz count
START_NS = 1_700_000_000_000_000_000
INGEST = load_params()["tool_ingest"]
SYNC = {"max_gap_s": 0.2, "pair_rate_hz": 0, "reference": "first", "contact_n": 0.5, "normal_sign": 1}  # this rig reads +Fz


def force_curve(t):
    """Two presses of 12 and 20 N, rest at 0 N before, between and after."""
    return 12 * np.exp(-((t - 2.0) / 0.5) ** 2) + 20 * np.exp(-((t - 5.0) / 0.6) ** 2)


def make_trial(session: Path, name: str, offset_s: float, kind: str = "normal", seconds: float = 7.0) -> Path:
    trial = session / name
    for s, gain in (("digit_left", 1.0), ("digit_right", 0.6)):
        d = trial / s
        d.mkdir(parents=True)
        t = np.arange(0, seconds, 1 / 30)
        yy, xx = np.mgrid[0:FRAME_H, 0:FRAME_W]
        base = np.stack([90 + 40 * xx / FRAME_W, 110 + 30 * yy / FRAME_H, 150 + 0 * xx], -1)
        lines = ["frame,host_ns"]
        for i, ti in enumerate(t):
            blob = gain * 4 * force_curve(ti) * np.exp(-((xx - 120) ** 2 + (yy - 160) ** 2) / 900.0)
            img = np.clip(base + blob[..., None], 0, 254).astype(np.uint8)
            # a camera's noise: no two exposures are the same bytes (ingest drops a repeat as a stale buffer)
            img += np.random.default_rng([i, len(s), len(name)]).integers(0, 2, img.shape, dtype=np.uint8)
            if s == "digit_right":                          # its own DIGIT: not the other finger's view
                img = np.ascontiguousarray(img[:, ::-1])
            cv2.imwrite(str(d / f"frame_{i:06d}.png"), img)
            lines.append(f"{i},{START_NS + int(ti * 1e9) + (3_000_000 if s == 'digit_right' else 0)}")
        (d / "frames.csv").write_text("\n".join(lines) + "\n")
    # the Arduino clock starts when the port opens; the host header is off by offset_s
    # the port opens before the cameras start and closes after them, as on the rig: every frame
    # has force samples on both sides once the clocks are aligned
    ft = np.arange(-0.5, seconds + 0.5, 1 / 15)
    volts_z = force_curve(ft) / CAL[2, 2]
    counts = np.full((len(ft), 6), 512)
    counts[:, 2] = np.round(512 + volts_z * 1023 / 5).astype(int)
    arduino_ms = np.round((ft + offset_s) * 1000).astype(int) + 1000
    header_ns = START_NS - 1_000_000_000
    rows = [f"# start_host_ns={header_ns}"] + [",".join(map(str, [ms, *c])) for ms, c in zip(arduino_ms, counts)]
    (trial / "force.log").write_text("\n".join(rows) + "\n")
    TrialMeta(trial=name, tool="screwdriver_1", kind=kind, orientation_deg=5.0, insertion_mm=14.0).write(trial)
    return trial


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    s = tmp_path_factory.mktemp("tool") / "lab-1"
    s.mkdir()
    write_calibration(s / "nano17.cal", CAL)
    make_trial(s, "t00", offset_s=0.25)
    make_trial(s, "t01", offset_s=-0.15)
    return s


def test_native_trial_reads_frames_and_calibrated_force(session):
    raw = read_native_trial(session / "t00")
    assert raw.tool == "screwdriver_1" and raw.kind == "normal"
    assert len(raw.frames["digit_left"]) == 210
    assert raw.frames["digit_left"].load(0).shape == (FRAME_H, FRAME_W, 3)
    assert raw.force_n[:, 2].max() == pytest.approx(20.0, abs=0.3)       # within ADC resolution
    assert raw.clock["refine"]


@pytest.mark.parametrize("trial, offset", [("t00", 0.25), ("t01", -0.15)])
def test_ingest_finds_the_clock_offset(session, tmp_path, trial, offset):
    info = ingest_trial(read_native_trial(session / trial), tmp_path / "s.parquet", image_size=32, ingest=INGEST)
    # the coarse force time is off by -offset (Arduino ahead); refinement must undo it
    assert info["clock"]["refined_shift_s"] == pytest.approx(-offset, abs=0.02)
    assert read_shard_info(tmp_path / "s.parquet")["frames"] == {"digit_left": 210, "digit_right": 210}


def test_dataset_pairs_frames_with_synced_forces(session, tmp_path):
    shards = []
    for trial in ("t00", "t01"):
        ingest_trial(read_native_trial(session / trial), tmp_path / f"{trial}.parquet", image_size=32, ingest=INGEST)
        shards.append(tmp_path / f"{trial}.parquet")
    build_tool_dataset(shards, "normal", tmp_path / "data", SYNC)
    data = ToolFrames(tmp_path / "data", "fz")
    assert len(data) > 390 and data.frames.shape[1:] == (2, 32, 32)
    t = data.samples["t_s"].to_numpy()
    truth = force_curve(t)
    assert np.abs(data.labels - truth).max() < 0.6            # synced within the ADC and interpolation error
    x, y = data.arrays(np.array([5, 1, 3]))
    assert x.shape == (3, 4, 32, 32) and x.dtype == np.uint8
    assert np.array_equal(x[:, 1], np.broadcast_to(data.references[0, 0], (3, 32, 32)))
    qc = json.loads((tmp_path / "data" / "qc.json").read_text())
    assert [t["pairs"] for t in qc["trials"]] == [len(data.samples[data.samples.trial_index == k]) for k in (0, 1)]


def test_pairs_are_thinned_to_the_pair_rate_without_counting_drops(session, tmp_path):
    ingest_trial(read_native_trial(session / "t00"), tmp_path / "t00.parquet", image_size=32, ingest=INGEST)
    for rate, out in ((0, "every"), (15, "at15")):
        build_tool_dataset([tmp_path / "t00.parquet"], "normal", tmp_path / out, {**SYNC, "pair_rate_hz": rate})
    every, at15 = ToolFrames(tmp_path / "every", "fz"), ToolFrames(tmp_path / "at15", "fz")
    assert len(at15) == (len(every) + 1) // 2                 # 30-FPS frames: every second pair
    assert np.allclose(np.diff(at15.samples["t_s"]), 2 / 30, atol=0.005)
    assert np.array_equal(at15.frames[:], every.frames[::2]) and np.array_equal(at15.labels, every.labels[::2])
    assert np.array_equal(at15.references[:], every.references[:])   # still frame 0 of the trial
    qc = [json.loads((tmp_path / d / "qc.json").read_text())["trials"][0] for d in ("every", "at15")]
    # the frames left out are not drops (force-gap drops are counted among the pairs kept)
    assert qc[0]["drops"]["unpaired frame"] == qc[1]["drops"]["unpaired frame"] == 0
    assert (qc[0]["pair_every"], qc[1]["pair_every"]) == (1, 2)


def test_force_gaps_drop_frames_and_are_counted(session, tmp_path):
    trial = tmp_path / "lab-1" / "gap"
    shutil.copytree(session / "t00", trial)
    shutil.copy(session / "nano17.cal", tmp_path / "lab-1")
    lines = (trial / "force.log").read_text().splitlines()
    (trial / "force.log").write_text("\n".join(lines[:40] + lines[55:]) + "\n")   # 1 s of serial missing
    ingest_trial(read_native_trial(trial), tmp_path / "g.parquet", image_size=32, ingest=INGEST)
    build_tool_dataset([tmp_path / "g.parquet"], "normal", tmp_path / "data", SYNC)
    qc = json.loads((tmp_path / "data" / "qc.json").read_text())
    dropped = qc["trials"][0]["drops"]["force gap"]
    gap_s = 16 / 15                     # 15 samples removed: the bracketing samples are 16 periods apart
    assert abs(dropped - gap_s * 30) <= 3           # every 30 fps frame inside the gap, give or take the edges


def _broken_copy(session, tmp_path, break_it):
    root = tmp_path / "lab-1"
    shutil.copytree(session, root)
    trial = root / "t00"
    break_it(trial)
    return trial


@pytest.mark.parametrize("break_it, needle", [
    (lambda t: (t / "digit_left" / "frame_000005.png").unlink(), "files are missing"),
    (lambda t: (t / "digit_left" / "frame_000003.png").write_bytes(b"not a png"), "unreadable"),
    (lambda t: cv2.imwrite(str(t / "digit_right" / "frame_000002.png"), np.zeros((240, 320, 3), np.uint8)),
     "the sensor's first frame is 240x320"),
    (lambda t: cv2.imwrite(str(t / "digit_right" / "frame_000002.png"), np.zeros((320, 240), np.uint8)),
     "grayscale image"),
    (lambda t: (t / "force.log").write_text("# start_host_ns=1\n100,1,1,1,1,1,1\n50,1,1,1,1,1,1\n"),
     "jumps back"),
    (lambda t: (t / "meta.json").unlink(), "meta.json"),
    (lambda t: (t.parent / "nano17.cal").unlink(), "calibration"),
    (lambda t: (t / "digit_left" / "frames.csv").write_text("frame,host_ns\n0,10\n1,5\n"), "do not increase"),
    (lambda t: shutil.rmtree(t / "digit_right"), "missing sensor folder"),
])
def test_bad_trials_raise_clear_errors(session, tmp_path, break_it, needle):
    trial = _broken_copy(session, tmp_path, break_it)
    with pytest.raises(InputError) as err:
        raw = read_native_trial(trial)
        ingest_trial(raw, tmp_path / "out.parquet", image_size=32, ingest=INGEST)
    assert needle in str(err.value)
    assert "lab-1" in str(err.value)                    # names the file
    assert not (tmp_path / "out.parquet").exists()
    assert not list(tmp_path.glob(".out.parquet*"))


def test_a_calibration_in_pounds_force_is_converted_to_newtons(tmp_path):
    from tactilepipe.tool.formats.native_layout import read_calibration, write_calibration
    write_calibration(tmp_path / "n.cal", CAL)
    text = (tmp_path / "n.cal").read_text()
    lbf = CAL.copy()
    lbf[:3] /= 4.4482216152605              # force rows in lbf per volt
    lbf[3:] /= 112.98482933                 # torque rows in lbf-in per volt
    write_calibration(tmp_path / "lbf.cal", lbf)
    (tmp_path / "lbf.cal").write_text((tmp_path / "lbf.cal").read_text().replace(
        'ForceUnits="N" TorqueUnits="N-mm"', 'ForceUnits="lbf" TorqueUnits="lbf-in"'))
    assert 'ForceUnits="N"' in text
    np.testing.assert_allclose(read_calibration(tmp_path / "lbf.cal"), read_calibration(tmp_path / "n.cal"), rtol=1e-7)


def test_a_force_log_that_starts_mid_press_is_left_out_and_named(smoke_params, tmp_path):
    from support.tool_sim import write_session
    from tactilepipe.tool.sim.plan import session_plan
    session = tmp_path / "lab-2"
    names = [t.name for t in session_plan(smoke_params) if t.kind == "normal"][:2]
    write_session(session, smoke_params, trials=names)
    trial = session / names[0]
    raw = read_native_trial(trial)
    sync = {**smoke_params["tool_sync"]}
    normal = sync["normal_sign"] * raw.force_n[:, 2]
    lines = (trial / "force.log").read_text().splitlines()
    start = int(np.argmax(normal > 0.5 * normal.max()))      # the log starts half-way up the press
    (trial / "force.log").write_text("\n".join([lines[0], *lines[1 + start:]]) + "\n")
    ingest = smoke_params["tool_ingest"]
    for name in names:
        ingest_trial(read_native_trial(session / name), tmp_path / f"{name}.parquet", image_size=32, ingest=ingest)
    shards = [tmp_path / f"{name}.parquet" for name in names]
    build_tool_dataset(shards, "normal", tmp_path / "data", sync)
    qc = json.loads((tmp_path / "data" / "qc.json").read_text())
    assert [t["trial"] for t in qc["trials"]] == [f"lab-2/{names[1]}"]
    (left,) = qc["dropped_trials"]
    # the witness of the rest level at both ends names it first (tool/data/witness.py), in either direction
    assert left["trial"] == f"lab-2/{names[0]}" and "witness 'rest at both ends'" in left["reason"]
    assert "taken under load" in left["reason"]
    with pytest.raises(InputError, match=f"no 'normal' trials among 1 shards .*lab-2/{names[0]}: witness 'rest at both"):
        build_tool_dataset(shards[:1], "normal", tmp_path / "data2", sync)


def test_a_normal_force_negative_throughout_points_at_the_sign_not_the_zero():
    from tactilepipe.tool.data.dataset import bad_zero
    press = np.zeros((100, 3))
    press[:, 2] = 10 * np.sin(np.linspace(0, np.pi, 100))          # one press of 10 N on +Fz
    assert bad_zero(press, 1) is None
    assert "tool_sync.normal_sign has the wrong sign" in bad_zero(press, -1)
    assert bad_zero(press - [0, 0, 4], 1).startswith("loaded start: the normal force reads -3.37 N (5th percentile")


@pytest.mark.parametrize("stamp, problem", [
    (lambda ns: ns + 10_000_000_000, r"the cameras are not on one clock: digit_left records .* digit_right .*"
                                     r"overlap by 0.000 s"),
    (lambda ns: ns // 1_000_000, r"digit_right: frames 3.3e-08 s apart \(median\): host_ns in another unit")])
def test_a_camera_on_another_clock_is_refused_at_ingest(session, tmp_path, stamp, problem):
    trial = tmp_path / "lab-1" / "clock"
    shutil.copytree(session / "t00", trial)
    shutil.copy(session / "nano17.cal", tmp_path / "lab-1")
    index = trial / "digit_right" / "frames.csv"
    lines = index.read_text().splitlines()
    index.write_text("\n".join([lines[0]] + [f"{i},{stamp(int(ns))}" for i, ns in
                                             (line.split(",") for line in lines[1:])]) + "\n")
    with pytest.raises(InputError, match=problem):
        ingest_trial(read_native_trial(trial), tmp_path / "s.parquet", image_size=32, ingest=INGEST)


# --- the true cause, at the first stage that can see it (through `tactilepipe tool-ingest`) ----------

def _cli_ingest(trial: Path, out: Path, capsys) -> tuple[int, str, str]:
    from tactilepipe.cli.main import main
    status = main(["tool-ingest", str(trial), "--format", "native", "--out", str(out)])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def _rewrite_clock(trial: Path, clock, started_ms: int = 0) -> None:
    """force.log with each Arduino time t (ms) replaced by clock(t); ``started_ms``: the board's
    clock read that much when the port opened (the header moves back by it, as if its clock had
    started then)."""
    lines = (trial / "force.log").read_text().splitlines()
    header = f"# start_host_ns={int(lines[0].split('=')[1]) - started_ms * 1_000_000}"
    rows = [ln.split(",", 1) for ln in lines[1:]]
    (trial / "force.log").write_text("\n".join([header] + [f"{clock(int(t))},{rest}" for t, rest in rows]) + "\n")


def test_a_micros_clock_that_wraps_mid_trial_is_unwrapped_and_named(session, tmp_path, capsys):
    status, out, err = _cli_ingest(session / "t00", tmp_path / "clean.parquet", capsys)
    assert status == 0, err
    clean = json.loads(out)["clock"]
    # a firmware printing micros()/1000, whose counter passes 2**32 us 3.5 s into the trial
    base_us = 2**32 - 4_500_000
    trial = _broken_copy(session, tmp_path, lambda t: _rewrite_clock(
        t, lambda ms: ((ms * 1000 + base_us) % 2**32) // 1000, started_ms=base_us // 1000))
    status, out, err = _cli_ingest(trial, tmp_path / "wrapped.parquet", capsys)
    assert status == 0, err
    clock = json.loads(out)["clock"]
    assert len(clock["arduino_wraps"]) == 1 and clock["arduino_wraps"][0].startswith("micros()/1000 at line ")
    # the same alignment as the clean log (its times are the clean ones plus a constant, to 1 ms)
    assert abs(clock["refined_shift_s"] - clean["refined_shift_s"]) < 0.002, (clock, clean)


def test_a_wrap_with_samples_missing_after_it_is_named_as_such_not_as_a_reset(session, tmp_path, capsys):
    base_us = 2**32 - 4_500_000

    def clock(ms):                        # 3 s of samples lost where the counter wraps
        us = ms * 1000 + base_us
        return ((us + (3_000_000 if us >= 2**32 else 0)) % 2**32) // 1000
    trial = _broken_copy(session, tmp_path, lambda t: _rewrite_clock(t, clock, started_ms=base_us // 1000))
    status, _, err = _cli_ingest(trial, tmp_path / "o.parquet", capsys)
    assert status == 2 and "force.log" in err, err
    assert re.search(r"Arduino clock wraps from 42949\d\d to \d+ ms \(its micros\(\)/1000 counter passing "
                     r"4294967.296 ms\) with 30\d\d ms between the samples", err), err
    assert "samples are missing there, not unwrapped" in err and "reset" not in err


@pytest.mark.parametrize("cal, needle", [
    (lambda text: text.replace("<FTSensor", '<FTSensor xmlns="http://www.ati-ia.com/calibration"', 1),
     "nano17.cal: the XML declares the namespace 'http://www.ati-ia.com/calibration' (xmlns): ATI's calibration "
     "files have none"),
    (lambda text: text.replace('values="0 0 20', 'values="0 0 1e300', 1),
     "nano17.cal [UserAxis Fz]: value 3 of the row, 1e+300, is out of range: alone it maps the ADC's 5 V to 5e+300 N"),
], ids=["namespaced_xml", "one_cell_1e300"])
def test_a_calibration_file_names_its_true_fault(session, tmp_path, capsys, cal, needle):
    trial = _broken_copy(session, tmp_path, lambda t: (t.parent / "nano17.cal").write_text(
        cal((t.parent / "nano17.cal").read_text())))
    status, _, err = _cli_ingest(trial, tmp_path / "o.parquet", capsys)
    assert status == 2 and needle in err, err
    assert "missing" not in err and "singular" not in err
