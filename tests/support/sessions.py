"""Synthetic tool-rig recordings the reader tests start from: a native-layout session (DIGIT
frames, serial force log, meta.json, nano17.cal), a public-layout session, a ROS bag trial in each
format, and the ingest settings they are read with (clock refinement refusing, not leaving out, a
trial it cannot align). The bad-input corpus breaks these; other tests read them as they are."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from support import ros_writer
from support.public_formats import write_public_trial
from tactilepipe.core.config import load_params
from tactilepipe.tool.formats import rosbag as ri
from tactilepipe.tool.formats.native_layout import FRAME_H, FRAME_W, TrialMeta, write_calibration

START_NS = 1_700_000_000_000_000_000
CAL = np.diag([8.0, 8.0, 20.0, 100.0, 100.0, 100.0])
SYNC = {"max_gap_s": 0.2, "pair_rate_hz": 0, "reference": "first", "contact_n": 0.5, "normal_sign": 1}
SIZE = 32                                           # ingest image size
# clock refinement as params.yaml sets it, but refusing (not leaving out) a trial it cannot align,
# so that each bad-input case's message can be checked; the drop path is tested in test_clock_sync.py
INGEST = load_params()["tool_ingest"]
INGEST["clock"]["on_low_score"] = "refuse"
N_FRAMES, N_FORCE = 24, 40


# --- good inputs (the bad-input corpus breaks them) ----------------------------------------------

def digit_frame(i: int, h: int = FRAME_H, w: int = FRAME_W) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w]
    blob = 40 * np.exp(-((xx - w / 2) ** 2 + (yy - h / 2) ** 2) / (30.0 + 20 * i))
    img = np.stack([90 + 40 * xx / w + blob, 110 + 30 * yy / h, 150 - blob], -1)
    return np.clip(img, 0, 255).astype(np.uint8)


def finger_frame(sensor: str, img: np.ndarray) -> np.ndarray:
    """The frame as the named finger's own DIGIT shows it: the right one mirrored (two cameras never
    deliver the same bytes; the importer refuses one camera's frames given for both fingers)."""
    return img if sensor == "digit_left" else np.ascontiguousarray(img[:, ::-1])


def noisy(img: np.ndarray, seed: int = 0) -> np.ndarray:
    """A frame with camera noise (JPEGs of noise-free synthetic frames decode differently when cut)."""
    return np.clip(img + np.random.default_rng(seed).normal(0, 5, img.shape), 0, 255).astype(np.uint8)


def serial_lines(n: int = N_FORCE) -> list[str]:
    return [f"{1000 + 67 * i},512,512,{512 + (30 if 10 <= i < 20 else 0)},512,512,512" for i in range(n)]


def write_serial(path: Path, lines: list[str], header: str = f"# start_host_ns={START_NS - 10**9}",
                 end: bytes = b"\n") -> None:
    path.write_bytes("\n".join([header, *lines]).encode("latin-1") + end)


def make_native_session(root: Path) -> Path:
    session = root / "lab-1"
    trial = session / "t00"
    for s in ("digit_left", "digit_right"):
        (trial / s).mkdir(parents=True)
        rows = ["frame,host_ns"]
        for i in range(N_FRAMES):
            # a camera's noise never repeats a frame byte for byte (ingest drops a repeat as a stale buffer)
            frame = finger_frame(s, digit_frame(i))
            grain = np.random.default_rng([i, s == "digit_right"]).integers(0, 2, frame.shape, dtype=np.uint8)
            cv2.imwrite(str(trial / s / f"frame_{i:06d}.png"), np.minimum(frame, 254) + grain)
            rows.append(f"{i},{START_NS + i * 33_333_333 + (3_000_000 if s == 'digit_right' else 0)}")
        (trial / s / "frames.csv").write_text("\n".join(rows) + "\n")
    write_serial(trial / "force.log", serial_lines())
    TrialMeta(trial="t00", tool="screwdriver_1", kind="normal", orientation_deg=5.0, insertion_mm=14.0).write(trial)
    write_calibration(session / "nano17.cal", CAL)
    return session


def make_public_session(root: Path) -> Path:
    session = root / "pub"
    n = 6
    frames = [digit_frame(i, 48, 64) for i in range(n)]
    write_public_trial(session, "t0", frames, frames, [0.5, 3.0, 6.0, 9.0, 6.0, 3.0], "normal")
    write_public_trial(session, "s0", frames, frames, np.full((n, 3), 1.0), "shear")
    (session / "trials.csv").write_text("trial,tool,orientation_deg,insertion_mm\nt0,knife,5,10\ns0,knife,5,10\n")
    return session


def write_ros(path: Path, fmt: str, left=None, right=None, force=None) -> Path:
    n = N_FRAMES // 3
    left = [digit_frame(i, 48, 64) for i in range(n)] if left is None else left
    right = left if right is None else right
    stamps = START_NS + 33_333_333 * np.arange(len(left), dtype=np.int64)
    force_ns = START_NS + 16_666_667 * np.arange(2 * n, dtype=np.int64)
    force = np.zeros((2 * n, 3)) if force is None else force
    ros_writer.write_ros_trial(path, left, right, stamps, force_ns, force, fmt, compressed=False)
    ri.sidecar_path(path).write_text(json.dumps({"tool": "knife", "kind": "normal", "orientation_deg": 0.0,
                                                 "insertion_mm": 10.0}))
    return path
