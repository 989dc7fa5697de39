"""The public dataset layout of study 000 and its reader (the importer).

    <root>/data_normal/<trial>/tactile1/tactile_frame_NNNN.jpg    first DIGIT (.jpg, .jpeg or .png)
                               tactile2/tactile_frame_NNNN.jpg    second DIGIT
                               force/force_data_NNNN.txt          one line per frame
    <root>/data_shear/<trial>/...                                 same, shear trials

Frames and force files are paired by their index NNNN (the public code pairs them by sorted
index). Normal force files hold one comma-separated line whose last field is the rig's raw
Arduino count; the label is -0.0302 * raw + 29.229 N (raw ~ 968 at 0 N) and frames whose label
is below 0 N are dropped, as the public code does. Shear force files hold one line `fx,fy,fz`
(N); the label is the shear magnitude sqrt(fx^2 + fy^2), Savitzky-Golay smoothed over the trial
(window 11, order 2). The zero-force reference of a trial is its first frame, also when that
frame's own label is dropped (as the public code does); ingest stores it in the shard.
"""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np
from scipy.signal import savgol_filter

from tactilepipe.core.errors import ArgumentError, InputError
from tactilepipe.core.rawfile import TABLE_MAX, read_raw_text
from tactilepipe.tool.formats.imagefile import read_image

KIND_DIRS = {"normal": "data_normal", "shear": "data_shear"}
SENSOR_DIRS = ("tactile1", "tactile2")
FORCE_DIR = "force"
FRAME_FILE = "tactile_frame_{:04d}.jpg"
FORCE_FILE = "force_data_{:04d}.txt"
FRAME_RE = re.compile(r"^tactile_frame_(\d+)\.(?:jpe?g|png)$", re.IGNORECASE)   # JPEG as published; PNG too
FORCE_RE = re.compile(r"^force_data_(\d+)\.txt$")
NORMAL_SLOPE_N = -0.0302            # N per raw count (the public code's conversion)
NORMAL_INTERCEPT_N = 29.229         # N at raw count 0
SAVGOL_WINDOW, SAVGOL_ORDER = 11, 2


def normal_from_raw(raw) -> np.ndarray:
    return NORMAL_SLOPE_N * np.asarray(raw, np.float64) + NORMAL_INTERCEPT_N


def smooth_shear(shear_n: np.ndarray) -> np.ndarray:
    """Savitzky-Golay smoothing (window 11, order 2); shorter trials use the longest odd window
    that fits (>= 3), trials of fewer than 3 frames are left as they are."""
    n = len(shear_n)
    window = min(SAVGOL_WINDOW, n if n % 2 else n - 1)
    if window <= SAVGOL_ORDER:
        return np.asarray(shear_n, np.float64)
    return savgol_filter(np.asarray(shear_n, np.float64), window, SAVGOL_ORDER)


def _check_kind(kind: str) -> None:
    if kind not in KIND_DIRS:
        raise ArgumentError(f"kind '{kind}' must be one of {sorted(KIND_DIRS)}")


def _indexed(folder: Path, pattern: re.Pattern, what: str) -> dict[int, Path]:
    if not folder.is_dir():
        raise InputError(folder, f"missing: every public trial needs a {folder.name}/ folder of {what}")
    found: dict[int, Path] = {}
    for path in sorted(folder.iterdir()):
        m = pattern.match(path.name)
        if not m:
            continue                      # stray files (thumbnails, .DS_Store) are not data
        idx = int(m.group(1))
        if idx in found:
            raise InputError(path, f"index {idx} also used by {found[idx].name}")
        found[idx] = path
    return found


def _parse_force(path: Path, kind: str) -> np.ndarray:
    try:
        text = read_raw_text(path, TABLE_MAX, "force file")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, f"unreadable force file: {exc}") from None
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines:
        raise InputError(path, "empty force file")
    fields = [f.strip() for f in lines[0].split(",")]
    try:
        if kind == "normal":
            values = np.array([float(fields[-1])])
        else:
            if len(fields) != 3:
                raise InputError(path, f"expected 'fx,fy,fz', got {lines[0]!r}", "line 1")
            values = np.array([float(f) for f in fields])
    except ValueError:
        what = f"last field {fields[-1]!r}" if kind == "normal" else f"line {lines[0]!r}"
        raise InputError(path, f"{what} is not a number", "line 1") from None
    if not np.isfinite(values).all():
        raise InputError(path, f"non-finite force value in {lines[0]!r}", "line 1")
    return values


def _read_frame(path: Path) -> np.ndarray:
    return read_image(path, cv2.IMREAD_COLOR)


def read_public_trial(trial_dir: str | Path, kind: str) -> dict:
    """Read one public trial: frames of both sensors, labels in N, frame indices, dropped rows.

    Returns dict(frames_left, frames_right: lists of BGR uint8 images, force_n: labels (N),
    index: the NNNN index of each kept frame, dropped: number of frames dropped because their
    normal label is below 0 N, reference_left / reference_right: the trial's first frame (lowest
    index), the zero-force reference, kept even when its own label was dropped). Raises
    InputError naming the file for missing, unpaired, unreadable or non-numeric files.
    """
    _check_kind(kind)
    trial_dir = Path(trial_dir)
    if not trial_dir.is_dir():
        raise InputError(trial_dir, "missing: no such trial folder")
    sides = [_indexed(trial_dir / s, FRAME_RE, "tactile_frame_NNNN.jpg (or .png)") for s in SENSOR_DIRS]
    forces = _indexed(trial_dir / FORCE_DIR, FORCE_RE, "force_data_NNNN.txt")
    for sub, frames in zip(SENSOR_DIRS, sides):
        for idx in sorted(set(frames) - set(forces)):
            raise InputError(frames[idx], f"no force file {FORCE_DIR}/{FORCE_FILE.format(idx)} for this frame")
        for idx in sorted(set(forces) - set(frames)):
            raise InputError(forces[idx], f"no {sub}/{FRAME_FILE.format(idx)} for this force file")
    index = np.array(sorted(forces), np.int64)
    first = int(index[0]) if len(index) else None
    if len(index) == 0:
        raise InputError(trial_dir / FORCE_DIR, "no force_data_NNNN.txt files: empty trial")
    values = np.stack([_parse_force(forces[i], kind) for i in index])
    dropped = 0
    if kind == "normal":
        label = normal_from_raw(values[:, 0])
        keep = label >= 0.0
        dropped = int((~keep).sum())
        label, index = label[keep], index[keep]
    else:
        label = smooth_shear(np.hypot(values[:, 0], values[:, 1]))
    left = [_read_frame(sides[0][i]) for i in index]
    right = [_read_frame(sides[1][i]) for i in index]
    ref_left = left[0] if len(index) and index[0] == first else _read_frame(sides[0][first])
    ref_right = right[0] if len(index) and index[0] == first else _read_frame(sides[1][first])
    for sub, frames, ref in zip(SENSOR_DIRS, (left, right), (ref_left, ref_right)):
        for i, img in zip(index, frames):
            if img.shape != ref.shape:
                raise InputError(trial_dir / sub / FRAME_FILE.format(i),
                                 f"frame size {img.shape} differs from the trial's first frame {ref.shape}")
    return {"frames_left": left, "frames_right": right, "force_n": label, "index": index, "dropped": dropped,
            "reference_left": ref_left, "reference_right": ref_right}
