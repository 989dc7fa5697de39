"""The rig's own layout (tool/formats/native_layout.py) -> RawTrial.

The force is put on the host clock here: from each serial line's arrival time where the recorder
stamped them (force_arrival.csv), else coarsely (port-open time + Arduino ms), and then ingest
refines the offset by cross-correlation once the frames are decoded (clock["refine"] = True).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from tactilepipe.core.errors import InputError
from tactilepipe.tool.formats.arrival_log import ARRIVAL_NAME, arduino_clock
from tactilepipe.tool.formats.imagefile import read_image
from tactilepipe.tool.formats.native_layout import (DIGIT_SIZES, FRAME_NAME, SENSORS, TrialMeta, calibrate,
                                                     read_calibration, read_frame_table)
from tactilepipe.tool.formats.raw import RawTrial, SensorFrames
from tactilepipe.tool.formats.serial_log import read_serial_log


def read_bgr(path: Path, record: str | None = None) -> np.ndarray:
    """Read one frame; unreadable or truncated files, a size no DIGIT streams, or the wrong channel
    count are InputErrors. (That a sensor keeps one size is checked at ingest.)"""
    img = read_image(path, cv2.IMREAD_UNCHANGED, record)
    if img.ndim == 2:
        raise InputError(path, "grayscale image; a DIGIT frame has 3 channels (BGR)", record)
    if img.shape[2] != 3 or img.dtype != np.uint8:
        raise InputError(path, f"expected 3-channel uint8 BGR, got {img.shape[2]} channels of {img.dtype}", record)
    if img.shape[:2] not in DIGIT_SIZES:
        modes = ", ".join(f"{w}x{h}" for h, w in DIGIT_SIZES)
        raise InputError(path, f"frame is {img.shape[1]}x{img.shape[0]}, not a DIGIT resolution ({modes})", record)
    return img


def _sensor_frames(sensor_dir: Path) -> tuple[SensorFrames, int, int]:
    """The sensor's frames, how many frame files frames.csv does not list (left out, counted) and
    how many frame numbers it skips (frames the camera dropped: counted, the others kept)."""
    numbers, stamps = read_frame_table(sensor_dir)
    if len(stamps) == 0:
        raise InputError(sensor_dir / "frames.csv", "no frames")
    paths = [sensor_dir / FRAME_NAME.format(n) for n in numbers]
    missing = [p for p in paths if not p.exists()]
    if missing:
        raise InputError(missing[0], f"frames.csv lists {len(stamps)} frames but {len(missing)} files are missing")
    listed = {p.name for p in paths}
    extra = sum(1 for p in sensor_dir.glob("frame_*.png") if p.name not in listed)
    skipped = int(numbers[-1]) + 1 - len(numbers)
    return SensorFrames(stamps, lambda i: read_bgr(paths[i]), [str(p) for p in paths], numbers), extra, skipped


# Two DIGITs are stamped by their own capture threads and never deliver the same bytes: a trial
# whose fingers share more than this share of their stamps, or of their frame files byte for
# byte, holds one camera's frames twice (a folder copied, one device path given for both)
SAME_CAMERA_SHARE = 0.5


def _check_two_cameras(trial_dir: Path, frames: dict[str, SensorFrames]) -> None:
    """InputError when digit_left and digit_right hold one camera's frames: their frames.csv share
    most stamps, or their frame files are byte-identical for most frames (compared where the
    sizes agree, which two cameras' PNGs almost never do)."""
    left, right = (frames[s] for s in SENSORS)
    n = min(len(left), len(right))
    shared = int(np.isin(left.host_ns, right.host_ns).sum())
    files = {name: dict(zip(f.numbers.tolist(), map(Path, f.source))) for name, f in zip(SENSORS, (left, right))}
    pairs = [(a, files[SENSORS[1]][k]) for k, a in files[SENSORS[0]].items() if k in files[SENSORS[1]]]
    same = sum(1 for a, b in pairs if a.stat().st_size == b.stat().st_size and a.read_bytes() == b.read_bytes())
    found = [f"{shared} of {n} frames.csv stamps are the same"] if shared > SAME_CAMERA_SHARE * n else []
    found += [f"{same} of {n} frame files are byte-identical"] if same > SAME_CAMERA_SHARE * n else []
    if found:
        raise InputError(trial_dir, f"digit_left and digit_right hold one camera's frames ({' and '.join(found)}): "
                                    f"each finger's folder must come from its own DIGIT (one device given for both, "
                                    f"or a folder copied over the other?)")


def read_native_trial(trial_dir: str | Path, bias_window_s: float = 0.5) -> RawTrial:
    trial_dir = Path(trial_dir)
    session_dir = trial_dir.parent
    meta = TrialMeta.read(trial_dir)
    frames, extra, skipped = {}, {}, {}
    for sensor in SENSORS:
        if not (trial_dir / sensor).is_dir():
            raise InputError(trial_dir / sensor, "missing sensor folder")
        frames[sensor], extra[sensor], skipped[sensor] = _sensor_frames(trial_dir / sensor)
    _check_two_cameras(trial_dir, frames)
    log = read_serial_log(trial_dir / "force.log")
    matrix = read_calibration(session_dir / "nano17.cal")
    rest = log.arduino_ms <= log.arduino_ms[0] + bias_window_s * 1000
    if rest.sum() < 2:
        raise InputError(trial_dir / "force.log", f"fewer than 2 samples in the first {bias_window_s} s "
                                                  f"to take the zero-force bias from")
    force = calibrate(log.counts, matrix, log.counts[rest].mean(axis=0))[:, :3]
    arrivals = trial_dir / ARRIVAL_NAME
    if arrivals.exists():
        # each line stamped as it reached the host: the Arduino clock is their lower envelope
        # (tool/formats/arrival_log.py); the images only witness it, and give the session's
        # camera latency at the dataset stage (tool/data/session_clock.py)
        fit = arduino_clock(arrivals, log.line_numbers, log.arduino_ms)
        host_ns = fit.host_ns(log.arduino_ms)
        clock = {"method": "serial_arrival", "arrival": fit.record(),
                 "millis0_after_port_open_s": round((fit.offset_ns - log.start_host_ns) / 1e9, 4)}
    else:
        # only the port-open time: coarse (the Arduino boots a fraction of a second later), refined
        # against the images at ingest (tool/data/clock_sync.py)
        host_ns = log.start_host_ns + log.arduino_ms * 1_000_000
        clock = {"method": "serial_start+xcorr", "refine": True}
    steps = np.diff(log.arduino_ms)
    evidence = {"unloaded_counts": [round(float(v), 2) for v in log.counts[rest].mean(axis=0)],
                "declared_fps": float(meta.camera_fps), "declared_serial_hz": float(meta.serial_hz),
                "serial_hz": float(1000.0 / np.median(steps)) if len(steps) else None, "bias_window_s": bias_window_s,
                # each gauge's excursion, and which one a press along z moves most (tool/data/witness.py)
                "gauge_range_counts": [round(float(v), 2) for v in np.subtract(*np.percentile(log.counts, [99, 1], axis=0))],
                "press_gauge": int(np.argmax(np.abs(np.linalg.inv(matrix)[:, 2])))}
    return RawTrial(
        trial=f"{session_dir.name}/{trial_dir.name}", tool=meta.tool, kind=meta.kind,
        orientation_deg=meta.orientation_deg, insertion_mm=meta.insertion_mm, frames=frames,
        force_host_ns=host_ns, force_n=force, source=str(trial_dir),
        clock={**clock, **({"arduino_wraps": log.wraps} if log.wraps else {})}, evidence=evidence,
        drops={**{f"serial: {k}": v for k, v in log.drops.items()},
               **{f"{sensor}: frame files not in frames.csv": n for sensor, n in extra.items() if n},
               **{f"{sensor}: frames skipped by the camera": n for sensor, n in skipped.items() if n}})
