"""Faults of a recorded trial that reach its labels, written into a simulated trial's own files as
the rig would have recorded them (the force chain's calibration faults are in witness_faults.py).
Each takes the trial folder; those that need another trial take its folder too."""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np

from support.witness_faults import BIAS_WINDOW_S, _read_log, _write_log
from tactilepipe.tool.formats import native_layout as layout
from tactilepipe.tool.formats.arrival_log import ARRIVAL_NAME


def _arrivals(trial: Path) -> tuple[np.ndarray, np.ndarray]:
    rows = np.array([[int(v) for v in ln.split(",")] for ln in (trial / ARRIVAL_NAME).read_text().splitlines()[1:]])
    return rows[:, 0], rows[:, 1]


def _write_arrivals(trial: Path, lines: np.ndarray, host_ns: np.ndarray) -> None:
    (trial / ARRIVAL_NAME).write_text("line,host_ns\n" + "".join(f"{a},{b}\n" for a, b in zip(lines, host_ns)))


def drift(trial: Path, calibration: np.ndarray, fz_n: float) -> None:
    """The Nano17's zero creeps by ``fz_n`` on Fz from the end of the zero window to the log's end."""
    header, ms, counts = _read_log(trial)
    ramp = np.clip((ms - ms[0] - BIAS_WINDOW_S * 1000) / (ms[-1] - ms[0] - BIAS_WINDOW_S * 1000), 0, 1)
    dv = np.linalg.solve(calibration, np.array([0.0, 0.0, fz_n, 0.0, 0.0, 0.0]))
    _write_log(trial, header, ms, counts + ramp[:, None] * dv * layout.ADC_COUNTS / layout.ADC_VOLTS)


def open_gauge(trial: Path, channel: int) -> None:
    """One gauge's wire open: its channel floats at a level of its own, whatever the load."""
    header, ms, counts = _read_log(trial)
    counts = counts.astype(np.float64)
    counts[:, channel] = 600 + np.random.default_rng(channel).normal(0, 0.6, len(ms))
    _write_log(trial, header, ms, counts)


def arrivals_late(trial: Path, seconds: float) -> None:
    """Every serial line stamped ``seconds`` late (a reader that stamps after a buffer fills)."""
    lines, host_ns = _arrivals(trial)
    _write_arrivals(trial, lines, host_ns + int(seconds * 1e9))


def port_open_late(trial: Path, seconds: float) -> None:
    """No arrival stamps, and the port-open stamp ``seconds`` late."""
    (trial / ARRIVAL_NAME).unlink(missing_ok=True)
    text = (trial / "force.log").read_text().split("\n", 1)
    start = int(text[0].split("=")[1])
    (trial / "force.log").write_text(f"# start_host_ns={start + int(seconds * 1e9)}\n{text[1]}")


def samples_of(trial: Path, other: Path) -> None:
    """Another trial's serial samples under this trial's header and on its clock: the lines and their
    arrival stamps moved by the difference of the two port-open stamps."""
    mine = int((trial / "force.log").read_text().split("\n", 1)[0].split("=")[1])
    head, body = (other / "force.log").read_text().split("\n", 1)
    (trial / "force.log").write_text(f"# start_host_ns={mine}\n{body}")
    if (other / ARRIVAL_NAME).exists():
        lines, host_ns = _arrivals(other)
        _write_arrivals(trial, lines, host_ns - int(head.split("=")[1]) + mine)


def swap_cameras(trial: Path) -> None:
    """digit_left's folder holds digit_right's frames and stamps, and the other way round."""
    left, right = (trial / s for s in layout.SENSORS)
    tmp = trial / "swap"
    left.rename(tmp)
    right.rename(left)
    tmp.rename(right)


def one_camera_twice(trial: Path) -> None:
    """Both fingers' folders hold digit_left's recording."""
    shutil.rmtree(trial / "digit_right")
    shutil.copytree(trial / "digit_left", trial / "digit_right")


def _frames(trial: Path, sensor: str) -> list[Path]:
    return sorted((trial / sensor).glob("frame_*.png"))


def repeated_frames(trial: Path) -> None:
    """Every second frame of both cameras is the one before (a driver that re-delivers a buffer)."""
    for sensor in layout.SENSORS:
        paths = _frames(trial, sensor)
        for a, b in zip(paths[0::2], paths[1::2]):
            shutil.copy2(a, b)


def exposure_step(trial: Path, sensor: str, gain: float) -> None:
    """From the trial's middle on, one camera's exposure is ``gain`` times longer (auto-exposure)."""
    paths = _frames(trial, sensor)
    for p in paths[len(paths) // 2:]:
        img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED).astype(np.float32)
        cv2.imwrite(str(p), np.clip(img * gain, 0, 255).astype(np.uint8))


def exposure_step_on_both(trial: Path, gain: float) -> None:
    """The same exposure step on both cameras (a lighting change the whole rig sees)."""
    for sensor in layout.SENSORS:
        exposure_step(trial, sensor, gain)
