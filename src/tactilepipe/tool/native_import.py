"""The rig's own layout (tool/layout.py) -> RawTrial.

The force is put on the host clock coarsely here (port-open time + Arduino ms); ingest refines the
offset by cross-correlation once the frames are decoded (clock["refine"] = True).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from tactilepipe.errors import InputError
from tactilepipe.tool.layout import FRAME_H, FRAME_NAME, FRAME_W, SENSORS, TrialMeta, read_calibration, read_frame_index
from tactilepipe.tool.raw import RawTrial, SensorFrames
from tactilepipe.tool.serial_log import read_serial_log
from tactilepipe.tool.sync import calibrate


def read_bgr(path: Path, record: str | None = None, shape: tuple | None = (FRAME_H, FRAME_W, 3)) -> np.ndarray:
    """Read one frame; unreadable files, wrong size or channel count are InputErrors."""
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise InputError(path, "unreadable or missing image", record)
    if img.ndim == 2:
        raise InputError(path, f"grayscale image; a DIGIT frame has 3 channels (BGR)", record)
    if img.shape[2] != 3 or img.dtype != np.uint8:
        raise InputError(path, f"expected 3-channel uint8 BGR, got {img.shape[2]} channels of {img.dtype}", record)
    if shape is not None and img.shape != shape:
        raise InputError(path, f"frame is {img.shape[1]}x{img.shape[0]}, expected {shape[1]}x{shape[0]} "
                               f"(portrait QVGA)", record)
    return img


def _sensor_frames(sensor_dir: Path) -> SensorFrames:
    stamps = read_frame_index(sensor_dir)
    if len(stamps) == 0:
        raise InputError(sensor_dir / "frames.csv", "no frames")
    paths = [sensor_dir / FRAME_NAME.format(i) for i in range(len(stamps))]
    missing = [p for p in paths if not p.exists()]
    if missing:
        raise InputError(missing[0], f"frames.csv lists {len(stamps)} frames but {len(missing)} files are missing")
    return SensorFrames(stamps, lambda i: read_bgr(paths[i]), [str(p) for p in paths])


def read_native_trial(trial_dir: str | Path, bias_window_s: float = 0.5) -> RawTrial:
    trial_dir = Path(trial_dir)
    session_dir = trial_dir.parent
    meta = TrialMeta.read(trial_dir)
    frames = {}
    for sensor in SENSORS:
        if not (trial_dir / sensor).is_dir():
            raise InputError(trial_dir / sensor, "missing sensor folder")
        frames[sensor] = _sensor_frames(trial_dir / sensor)
    log = read_serial_log(trial_dir / "force.log")
    matrix = read_calibration(session_dir / "nano17.cal")
    rest = log.arduino_ms <= log.arduino_ms[0] + bias_window_s * 1000
    if rest.sum() < 2:
        raise InputError(trial_dir / "force.log", f"fewer than 2 samples in the first {bias_window_s} s "
                                                  f"to take the zero-force bias from")
    force = calibrate(log.counts, matrix, log.counts[rest].mean(axis=0))[:, :3]
    host_ns = log.start_host_ns + log.arduino_ms * 1_000_000
    return RawTrial(
        trial=f"{session_dir.name}/{trial_dir.name}", tool=meta.tool, kind=meta.kind,
        orientation_deg=meta.orientation_deg, insertion_mm=meta.insertion_mm, frames=frames,
        force_host_ns=host_ns, force_n=force, source=str(trial_dir),
        clock={"method": "serial_start+xcorr", "refine": True},
        drops={f"serial: {k}": v for k, v in log.drops.items()})
