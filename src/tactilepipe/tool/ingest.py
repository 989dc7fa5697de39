"""RawTrial -> one Parquet shard: preprocessed frames (grayscale, resized, PNG-encoded) of both
sensors with their times, and the force rows on the same clock.

Here a frame becomes a small grayscale image: BGR -> gray -> resize to ``image_size`` (area
interpolation), encoded losslessly. The force clock is refined against the images when the
importer asks for it (RawTrial.clock["refine"]).
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from tactilepipe.atomic import atomic_path
from tactilepipe.errors import InputError
from tactilepipe.tool.raw import RawTrial
from tactilepipe.tool.sync import estimate_offset


def preprocess(bgr: np.ndarray, size: int) -> np.ndarray:
    """What the models see of a frame: grayscale, size x size."""
    gray = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
    return cv2.resize(gray, (size, size), interpolation=cv2.INTER_AREA)


# A DIGIT frame always shows its LEDs' gradient over the gel: a frame that is (almost) all black
# (LEDs off, camera unplugged) or all white (over-exposed) carries no contact and is an error.
DARK_LEVEL, BRIGHT_LEVEL = 10, 245      # gray levels
BLANK_FRACTION = 0.95                   # of the (preprocessed) pixels


def check_frame(bgr: np.ndarray, first_shape: tuple | None, where: str, name: str) -> None:
    """InputError naming the frame unless it is BGR uint8 of the sensor's first frame's size."""
    if bgr.ndim != 3 or bgr.shape[2] != 3 or bgr.dtype != np.uint8:
        raise InputError(where, f"{name}: expected a 3-channel uint8 BGR frame, got {bgr.dtype} {bgr.shape}")
    if first_shape is not None and bgr.shape != first_shape:
        raise InputError(where, f"{name}: frame is {bgr.shape[1]}x{bgr.shape[0]}, the sensor's first frame is "
                                f"{first_shape[1]}x{first_shape[0]}")


def check_exposure(gray: np.ndarray, where: str, name: str) -> None:
    """InputError naming the frame if it is (almost) all black or all white."""
    if (gray <= DARK_LEVEL).mean() >= BLANK_FRACTION:
        raise InputError(where, f"{name}: frame is all black (LEDs off or camera not streaming?)")
    if (gray >= BRIGHT_LEVEL).mean() >= BLANK_FRACTION:
        raise InputError(where, f"{name}: frame is saturated (all white: over-exposed?)")


def _decode_sensor(frames, size: int, name: str) -> tuple[list[bytes], np.ndarray]:
    pngs, change = [], np.zeros(len(frames))
    first = None
    for i in range(len(frames)):
        bgr = frames.load(i)
        check_frame(bgr, None if first is None else first_shape, frames.source[i], name)
        first_shape = bgr.shape
        img = preprocess(bgr, size)
        check_exposure(img, frames.source[i], name)
        if first is None:
            first = img.astype(np.int16)
        change[i] = np.abs(img.astype(np.int16) - first).mean()
        ok, buf = cv2.imencode(".png", img, [cv2.IMWRITE_PNG_COMPRESSION, 1])
        if not ok:
            raise InputError(frames.source[i], f"{name}: cannot PNG-encode the preprocessed frame")
        pngs.append(buf.tobytes())
    return pngs, change


def ingest_trial(raw: RawTrial, shard: str | Path, image_size: int, max_offset_s: float = 1.0) -> dict:
    """Write the shard atomically; returns the trial's QC record (counts, clock offset found).

    The record's ``drops`` are the importer's counted drops by reason (e.g. "serial: garbage
    bytes", "serial: ADC saturated": Nano17 samples at the ADC rails, left out of the force rows);
    ``force_samples`` counts the force rows written, after those drops.
    """
    why = f" ({', '.join(f'{k} {v}' for k, v in raw.drops.items() if v)} dropped)" if any(raw.drops.values()) else ""
    empty = [name for name, frames in raw.frames.items() if len(frames) == 0]
    if empty or not raw.frames:
        raise InputError(raw.source, f"no frames of {empty or 'any sensor'} to ingest{why}")
    if len(raw.force_host_ns) == 0:     # e.g. every sample saturated or garbled (counted in raw.drops)
        raise InputError(raw.source, f"no force samples{why}")
    decoded = {name: _decode_sensor(frames, image_size, name) for name, frames in raw.frames.items()}
    force_ns = raw.force_host_ns.astype(np.int64)
    force = np.asarray(raw.force_n, np.float64)
    if not np.isfinite(force).all():
        bad = int(np.argmax(~np.isfinite(force).all(axis=1)))
        raise InputError(raw.source, "force is NaN or inf", f"force sample {bad}")
    clock = dict(raw.clock)
    if clock.get("refine"):
        # tactile change (both fingers) vs force magnitude, on the host clock in seconds
        ref = next(iter(raw.frames.values())).host_ns[0]
        name0 = next(iter(raw.frames))
        t_frames = (raw.frames[name0].host_ns - ref) / 1e9
        tactile = sum(np.interp(t_frames, (raw.frames[n].host_ns - ref) / 1e9, decoded[n][1]) for n in raw.frames)
        shift, score = estimate_offset(t_frames, tactile, (force_ns - ref) / 1e9,
                                       np.linalg.norm(force, axis=1), max_offset_s)
        force_ns = force_ns + int(round(shift * 1e9))
        clock.update({"refined_shift_s": shift, "xcorr": score})
    rows_sensor, rows_t, rows_png = [], [], []
    for name, (pngs, _) in decoded.items():
        rows_sensor += [name] * len(pngs)
        rows_t.append(raw.frames[name].host_ns.astype(np.int64))
        rows_png += pngs
    n_frames, n_force = len(rows_png), len(force_ns)
    table = pa.table({
        "row": pa.array(["frame"] * n_frames + ["force"] * n_force).dictionary_encode(),
        "sensor": pa.array(rows_sensor + [None] * n_force, pa.string()),
        "t_ns": pa.array(np.concatenate(rows_t + [force_ns])),
        "png": pa.array(rows_png + [None] * n_force, pa.binary()),
        "fx": pa.array(np.concatenate([np.full(n_frames, np.nan), force[:, 0]])),
        "fy": pa.array(np.concatenate([np.full(n_frames, np.nan), force[:, 1]])),
        "fz": pa.array(np.concatenate([np.full(n_frames, np.nan), force[:, 2]])),
    })
    info = {"trial": raw.trial, "tool": raw.tool, "kind": raw.kind, "orientation_deg": raw.orientation_deg,
            "insertion_mm": raw.insertion_mm, "image_size": image_size, "clock": clock,
            "drops": raw.drops, "frames": {n: len(f) for n, f in raw.frames.items()}, "force_samples": n_force,
            "source": raw.source}
    table = table.replace_schema_metadata({b"tactilepipe": json.dumps(info).encode()})
    with atomic_path(shard) as tmp:
        pq.write_table(table, tmp, compression="zstd")
    return info


def read_shard_info(shard: str | Path) -> dict:
    try:
        meta = pq.read_schema(shard).metadata or {}
    except FileNotFoundError:
        raise InputError(shard, "shard not found") from None
    except (OSError, pa.ArrowException) as exc:      # truncated, empty, not Parquet
        raise InputError(shard, f"cannot read shard (truncated or not Parquet?): {exc}") from None
    if b"tactilepipe" not in meta:
        raise InputError(shard, "not a tool shard (no tactilepipe metadata)")
    try:
        info = json.loads(meta[b"tactilepipe"])
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(shard, f"corrupt tactilepipe metadata: {exc}") from None
    if not isinstance(info, dict) or not {"kind", "image_size", "trial", "source"} <= set(info):
        raise InputError(shard, "tactilepipe metadata lacks kind, image_size, trial or source")
    return info
