"""RawTrial -> one Parquet shard: preprocessed frames (grayscale, resized, PNG-encoded) of both
sensors with their times, and the force rows on the same clock.

Here a frame becomes a small grayscale image: BGR -> gray -> resize to ``image_size`` (area
interpolation), encoded losslessly. The force clock is refined against the images when the
importer asks for it (RawTrial.clock["refine"]; tool/data/clock_sync.py), and a camera that froze
while the force changed is refused whatever the layout.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import cv2
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from tactilepipe.core.atomic import atomic_path
from tactilepipe.core.errors import InputError
from tactilepipe.tool.formats.native_layout import RATED_RANGE
from tactilepipe.tool.formats.raw import RawTrial
from tactilepipe.tool.data.clock_sync import change_signal, fit_offset, frozen_frames, frozen_runs, judge
from tactilepipe.tool.data.devices import one_camera_twice
from tactilepipe.tool.data.witness import chain_witness, label_witness


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


# Frames bit-identical over this many in a row: the camera re-delivered a stale buffer (a real
# sensor's noise never repeats an exposure). Harmless at rest, wrong labels while the force moves.
FROZEN_RUN = 3
# A force sample beyond twice the Nano17's rated range on an axis (±50, ±50, ±70 N; the study's
# presses stay under about 25 N) is no reading of this rig: a garbled value, another unit. It is
# left out of the force rows and counted, never turned into a label.
PLAUSIBLE_FORCE_N = 2.0 * RATED_RANGE[:3]
REPEATED = "frame repeats the one before byte for byte (a re-delivered buffer)"
BEYOND_RANGE = "force beyond twice the Nano17's rated range"


def _decode_sensor(frames, size: int, name: str) -> tuple[list[bytes], np.ndarray, list[int], np.ndarray]:
    """PNG bytes of every preprocessed frame, the frames themselves (n, size, size), the recorded
    frame size [width, height], and which frames repeat the one before byte for byte (as recorded:
    a real sensor's noise never repeats an exposure, so such a frame is a re-delivered buffer)."""
    pngs, grays = [], np.zeros((len(frames), size, size), np.uint8)
    repeats = np.zeros(len(frames), bool)
    first_shape, last = None, None
    for i in range(len(frames)):
        bgr = frames.load(i)
        check_frame(bgr, first_shape, frames.source[i], name)
        digest = hashlib.blake2b(bgr.tobytes(), digest_size=16).digest()
        repeats[i], last = digest == last, digest
        first_shape = bgr.shape
        img = preprocess(bgr, size)
        check_exposure(img, frames.source[i], name)
        grays[i] = img
        ok, buf = cv2.imencode(".png", img, [cv2.IMWRITE_PNG_COMPRESSION, 1])
        if not ok:
            raise InputError(frames.source[i], f"{name}: cannot PNG-encode the preprocessed frame")
        pngs.append(buf.tobytes())
    return pngs, grays, [int(first_shape[1]), int(first_shape[0])], repeats


def _image_fit(raw: RawTrial, grays: dict, force_ns: np.ndarray, force: np.ndarray, search: float, clock: dict):
    """The lag at which |F| best explains what both fingers see, and why it cannot be trusted (None
    when it can): a flat force log, a peak on the edge of the window, a low or split score."""
    mag = np.linalg.norm(force, axis=1)
    spread = float(mag.max() - mag.min())
    ref = next(iter(raw.frames.values())).host_ns[0]
    fingers = {n: ((f.host_ns - ref) / 1e9, change_signal(grays[n])) for n, f in raw.frames.items()}
    fit = fit_offset(fingers, (force_ns - ref) / 1e9, mag, search)
    if spread < clock["min_force_range_n"]:
        return fit, (f"the force log is flat (|F| varies by {spread:.3f} N < tool_ingest.clock.min_force_range_n "
                     f"{clock['min_force_range_n']} N): no press to align on")
    if fit.on_edge:
        return fit, (f"the best lag ({fit.shift_s:+.3f} s, correlation {fit.score:.2f}) is on the edge of the "
                     f"search window +-{search} s: the true lag may lie beyond it, or the images do not follow "
                     f"the force")
    return fit, judge(fit, clock, search)


def _refine_clock(raw: RawTrial, grays: dict, force_ns: np.ndarray, force: np.ndarray, ingest: dict
                  ) -> tuple[int, dict]:
    """Shift (ns) to add to the coarse force times, and the clock record; InputError when the
    offset cannot be found and the parameters say to refuse."""
    clock, search = ingest["clock"], ingest["max_offset_s"]
    fit, why = _image_fit(raw, grays, force_ns, force, search, clock)
    record = fit.record()
    if why is None:
        return int(round(fit.shift_s * 1e9)), record
    if clock["on_low_score"] == "refuse":
        raise InputError(raw.source, f"cannot align the force clock to the cameras: {why}")
    if clock["on_low_score"] == "drop":
        # the shard is written (the graph needs it) but marked: the dataset leaves the trial out
        print(f"warning: {raw.source}: left out of the dataset, force clock not aligned: {why}", file=sys.stderr)
        record.update({"refined_shift_s": 0.0, "dropped": f"clock not aligned: {why}"})
        return 0, record
    # host_clock: keep the port-open clock (good to ~0.1-0.5 s), say so now and in QC
    print(f"warning: {raw.source}: force clock not refined, host clock kept: {why}", file=sys.stderr)
    record.update({"refined_shift_s": 0.0, "fallback": f"host clock: {why}"})
    return 0, record


def _image_lag(raw: RawTrial, grays: dict, force_ns: np.ndarray, force: np.ndarray, ingest: dict) -> dict:
    """A force clock from arrival stamps is not moved: the images' own best lag is kept as evidence
    (the camera's exposure-to-stamp latency, pooled over the session at the dataset stage, and the
    witness of this trial's clock), with why it cannot be used where it cannot."""
    # the whole window: a clock off by more than a camera's latency must still show where it lies
    fit, why = _image_fit(raw, grays, force_ns, force, ingest["max_offset_s"], ingest["clock"])
    return {**fit.record(), "usable": why is None, **({"unusable": why} if why else {})}


def _check_frozen(raw: RawTrial, grays: dict, force_ns: np.ndarray, force: np.ndarray, limit_n: float,
                  whole_only: bool = False) -> None:
    """InputError for a camera whose frames are all bit-identical, or (unless ``whole_only``, used
    while the force clock is still coarse) stay identical while |F| changes by more than
    ``limit_n`` (its labels would follow the force, its images would not)."""
    mag = np.linalg.norm(force, axis=1)
    for name, frames in raw.frames.items():
        for a, b in frozen_runs(frozen_frames(grays[name]), FROZEN_RUN):
            if whole_only and not (a == 0 and b == len(frames) - 1):
                continue
            t0, t1 = frames.host_ns[a], frames.host_ns[b]
            inside = mag[(force_ns >= t0) & (force_ns <= t1)]
            ends = np.interp([t0, t1], force_ns, mag)
            seen = np.concatenate([inside, ends])
            change = float(seen.max() - seen.min())
            if change > limit_n or (a == 0 and b == len(frames) - 1):
                raise InputError(frames.source[a], f"{name}: frames {frames.number(a)}-{frames.number(b)} of {len(frames)} "
                                                   f"are bit-identical while "
                                                   f"|F| changes by {change:.2f} N: the camera froze")


def _reference_rows(raw: RawTrial, size: int) -> list[tuple[str, bytes]]:
    """(sensor, PNG) of each stored reference frame of the trial, preprocessed as its frames."""
    out = []
    for name, bgr in sorted(raw.reference.items()):
        where = f"{raw.source} (reference frame of {name})"
        check_frame(bgr, None, where, name)
        img = preprocess(bgr, size)
        check_exposure(img, where, name)
        ok, buf = cv2.imencode(".png", img, [cv2.IMWRITE_PNG_COMPRESSION, 1])
        if not ok:
            raise InputError(where, f"{name}: cannot PNG-encode the preprocessed reference frame")
        out.append((name, buf.tobytes()))
    return out


# A DIGIT streams at 15-60 fps: frame intervals outside 1/240 s to 1 s mean another time unit
FRAME_INTERVAL_S = (1 / 240, 1.0)


def _check_camera_clocks(raw: RawTrial) -> None:
    """Both cameras' stamps must be on the host clock in nanoseconds: intervals a DIGIT can have,
    and the two fingers recording at the same time (their spans overlap by half the shorter).
    A camera on another clock (epoch ms, another host) is refused here, naming it, instead of
    leaving a trial whose frames never meet a force sample."""
    spans = {}
    for name, frames in raw.frames.items():
        t = frames.host_ns.astype(np.float64)
        if len(t) > 1:
            step = float(np.median(np.diff(t))) / 1e9
            if not FRAME_INTERVAL_S[0] <= step <= FRAME_INTERVAL_S[1]:
                raise InputError(raw.source, f"{name}: frames {step:.3g} s apart (median): host_ns in another unit "
                                             f"than nanoseconds? A DIGIT streams at 15-60 fps")
        spans[name] = (t[0], t[-1])
    if len(spans) == 2:
        (a0, a1), (b0, b1) = spans.values()
        shorter = min(a1 - a0, b1 - b0)
        overlap = min(a1, b1) - max(a0, b0)
        if overlap < 0.5 * shorter or (shorter == 0 and overlap < 0):
            (na, _), (nb, _) = spans.items()
            raise InputError(raw.source, f"the cameras are not on one clock: {na} records {a0 / 1e9:.3f}-{a1 / 1e9:.3f} s, "
                                         f"{nb} {b0 / 1e9:.3f}-{b1 / 1e9:.3f} s (host clock), which overlap by "
                                         f"{max(overlap, 0) / 1e9:.3f} s; both must be stamped by the same host clock")


def ingest_trial(raw: RawTrial, shard: str | Path, image_size: int, ingest: dict) -> dict:
    """Write the shard atomically; returns the trial's QC record (counts, clock offset found).

    ``ingest``: params.yaml's tool_ingest group (max_offset_s and clock: how the force clock is
    refined and when a fit is refused).

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
    _check_camera_clocks(raw)
    decoded = {name: _decode_sensor(frames, image_size, name) for name, frames in raw.frames.items()}
    force_ns = raw.force_host_ns.astype(np.int64)
    force = np.asarray(raw.force_n, np.float64)
    if not np.isfinite(force).all():
        bad = int(np.argmax(~np.isfinite(force).all(axis=1)))
        raise InputError(raw.source, "force is NaN or inf", f"force sample {bad}")
    drops = dict(raw.drops)
    beyond = (np.abs(force) > PLAUSIBLE_FORCE_N).any(axis=1)
    if beyond.any():
        drops[BEYOND_RANGE] = int(beyond.sum())
        force_ns, force = force_ns[~beyond], force[~beyond]
        if len(force) == 0:
            worst = float(np.abs(np.asarray(raw.force_n, np.float64)).max())
            raise InputError(raw.source, f"every force sample lies beyond twice the Nano17's rated range "
                                         f"(±{PLAUSIBLE_FORCE_N[0]:g}, ±{PLAUSIBLE_FORCE_N[1]:g}, "
                                         f"±{PLAUSIBLE_FORCE_N[2]:g} N; up to {worst:.4g} N here)")
    clock = dict(raw.clock)
    grays = {name: d[1] for name, d in decoded.items()}
    # native trials: witnesses of every label, from outside the force chain (tool/data/witness.py)
    witness = chain_witness(raw.evidence, raw.frames, ingest["witness"]) \
        if raw.evidence and "witness" in ingest else None
    if clock.get("refine") and witness and witness["failed"]:
        # the counts or the stamps are not what they claim: no clock fit on them (its error would
        # name the clock); the trial is left out for the witness's cause
        clock.update({"refined_shift_s": 0.0, "dropped": "not aligned: " + "; ".join(witness["failed"])})
    elif clock.get("refine"):
        _check_frozen(raw, grays, force_ns, force, ingest["clock"]["min_force_range_n"], whole_only=True)
        shift_ns, record = _refine_clock(raw, grays, force_ns, force, ingest)
        force_ns = force_ns + shift_ns
        clock.update(record)
    elif clock.get("method") == "serial_arrival":
        _check_frozen(raw, grays, force_ns, force, ingest["clock"]["min_force_range_n"], whole_only=True)
        clock["images"] = _image_lag(raw, grays, force_ns, force, ingest)
    _check_frozen(raw, grays, force_ns, force, ingest["clock"]["min_force_range_n"])
    if witness is not None:
        same_view = one_camera_twice(raw.frames, grays)
        if same_view:
            witness["failed"]["one camera"] = same_view
        trusted = (bool(clock.get("refine")) or clock.get("method") == "serial_arrival") \
            and not clock.get("fallback") and not clock.get("dropped")
        label_witness(witness, raw.evidence, raw.frames, grays, force_ns, force, trusted, ingest["witness"])
        for name, why in witness["failed"].items():
            print(f"warning: {raw.source}: left out of the dataset, witness '{name}': {why}", file=sys.stderr)
    rows_sensor, rows_t, rows_png = [], [], []
    for name, (pngs, _, _, repeats) in decoded.items():
        # a repeated frame shows the moment before its stamp: left out, counted (a run of them
        # while the force moved was refused above as a frozen camera)
        if repeats.any():
            drops[f"{name}: {REPEATED}"] = int(repeats.sum())
        keep = np.flatnonzero(~repeats)
        rows_sensor += [name] * len(keep)
        rows_t.append(raw.frames[name].host_ns[keep].astype(np.int64))
        rows_png += [pngs[i] for i in keep]
    n_frames, n_force = len(rows_png), len(force_ns)
    refs = _reference_rows(raw, image_size)            # "reference" rows: a stored zero-force frame per sensor
    rows_sensor += [name for name, _ in refs]
    rows_t += [raw.frames[name].host_ns[:1].astype(np.int64) for name, _ in refs]
    rows_png += [png for _, png in refs]
    n_frames, kinds = len(rows_png), ["frame"] * n_frames + ["reference"] * len(refs)
    table = pa.table({
        "row": pa.array(kinds + ["force"] * n_force).dictionary_encode(),
        "sensor": pa.array(rows_sensor + [None] * n_force, pa.string()),
        "t_ns": pa.array(np.concatenate(rows_t + [force_ns])),
        "png": pa.array(rows_png + [None] * n_force, pa.binary()),
        "fx": pa.array(np.concatenate([np.full(n_frames, np.nan), force[:, 0]])),
        "fy": pa.array(np.concatenate([np.full(n_frames, np.nan), force[:, 1]])),
        "fz": pa.array(np.concatenate([np.full(n_frames, np.nan), force[:, 2]])),
    })
    info = {"trial": raw.trial, "tool": raw.tool, "kind": raw.kind, "orientation_deg": raw.orientation_deg,
            "insertion_mm": raw.insertion_mm, "image_size": image_size, "clock": clock,
            "drops": drops, "frames": {n: len(f) for n, f in raw.frames.items()}, "force_samples": n_force,
            "frame_size": {n: d[2] for n, d in decoded.items()},   # [w, h] before the square resize
            "source": raw.source}
    if witness is not None:
        info["witness"] = witness
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
