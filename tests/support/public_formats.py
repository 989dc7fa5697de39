"""Writers of study 000's public formats, for tests: a trial in the public dataset's layout and a
state dict under the public code's key names (the pipeline only reads these)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from tactilepipe.core.atomic import atomic_path, write_text
from tactilepipe.core.errors import ArgumentError
from tactilepipe.tool.formats import public_layout as pl
from tactilepipe.tool.model import public_weights as pw

JPEG_QUALITY = 95


def raw_from_normal(force_n) -> np.ndarray:
    """The public rig's raw Arduino count for a normal force (N), rounded to a whole count."""
    return np.rint((np.asarray(force_n, np.float64) - pl.NORMAL_INTERCEPT_N) / pl.NORMAL_SLOPE_N).astype(np.int64)


def write_public_trial(root: str | Path, trial_name: str, frames_left, frames_right, forces, kind: str,
                       time_ms=None) -> Path:
    """Write one trial in the public layout; returns its folder.

    frames_*: sequences of BGR uint8 images (JPEG, quality 95); forces: normal -> (n,) normal force
    in N (written as the raw count the public conversion maps back to it); shear -> (n, 3) fx, fy,
    fz in N. time_ms: optional first field of the normal lines (default: the frame index).
    """
    pl._check_kind(kind)
    n = len(frames_left)
    forces = np.asarray(forces, np.float64)
    want = (n,) if kind == "normal" else (n, 3)
    if len(frames_right) != n or forces.shape != want:
        raise ArgumentError(f"{trial_name}: {n} left frames, {len(frames_right)} right frames and forces "
                            f"of shape {forces.shape} (expected {want})")
    tdir = Path(root) / pl.KIND_DIRS[kind] / trial_name
    for sub, frames in zip(pl.SENSOR_DIRS, (frames_left, frames_right)):
        for i, img in enumerate(frames):
            ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
            if not ok:
                raise RuntimeError(f"JPEG encoding failed for frame {i} of {trial_name}")
            with atomic_path(tdir / sub / pl.FRAME_FILE.format(i)) as tmp:
                tmp.write_bytes(buf.tobytes())
    first = np.arange(n) if time_ms is None else np.asarray(time_ms, np.int64)
    raw = raw_from_normal(forces) if kind == "normal" else None
    for i in range(n):
        line = f"{first[i]},{raw[i]}" if kind == "normal" else ",".join(f"{v:.4f}" for v in forces[i])
        write_text(tdir / pl.FORCE_DIR / pl.FORCE_FILE.format(i), line + "\n")
    return tdir


def to_public(state: dict, head: str = "normal") -> dict:
    """Our ``full`` model's state dict under the public code's key names."""
    return {pw.to_public_key(k, head): v for k, v in state.items()}
