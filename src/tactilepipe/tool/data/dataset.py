"""Shards of one trial kind -> the training set of a tool scene (sync, references, QC).

For every trial: pair the two fingers' frames taken within half a frame period, optionally keep
every k-th pair to come down to ``pair_rate_hz`` (0: every pair; the paper pairs at 15 FPS), give each pair
the force interpolated at its time (dropped and counted where the force has a gap longer than
``max_gap_s``), choose the zero-force reference frame of each finger, and decode the images once
into memory-mappable arrays:

    samples.parquet   one row per frame pair: trial, tool, pose, t_s, fx, fy, fz (sensor frame), and
                      the two labels: normal (compressive force, normal_sign * fz) and shear
                      (sqrt(fx² + fy²))
    frames.npy        (pairs, 2, S, S) uint8: current frame of each finger
    references.npy    (trials, 2, S, S) uint8: reference frame of each finger
    qc.json           per trial: frames, pairs, drops by reason, clock offset found, force range;
                      the trials left out, each with its reason

A trial whose normal force (normal_sign * fz) dips clearly below zero had its zero-force offset
taken while loaded (the log started mid-press): every label of it is shifted by that load, so it
is left out and named (``loaded_start``). A press can only push: the simulated and real trials
met stay above -0.12 N, the threshold is -1 N on the 5th percentile.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from tactilepipe.core.atomic import atomic_path, open_memmap, write_json, write_parquet
from tactilepipe.core.errors import InputError
from tactilepipe.tool.data.ingest import read_shard_info
from tactilepipe.tool.formats.native_layout import frame_orientation
from tactilepipe.tool.formats.raw import SENSORS
from tactilepipe.tool.data.sync import interpolate_at, pair_frames
from tactilepipe.tool.data.session_clock import camera_latency, lag_outlier, shift_ns
from tactilepipe.tool.data.witness import session_outliers

LOADED_START_N = 1.0             # N: a normal force this far below zero (5th percentile) means a loaded zero


def _decode(png: bytes, where: str) -> np.ndarray:
    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise InputError(where, "cannot decode a frame stored in the shard")
    return img


def orientation(info: dict) -> str:
    """portrait, landscape or square, from the frame sizes a shard records (older shards: unknown)."""
    sizes = {tuple(v) for v in info.get("frame_size", {}).values()}
    kinds = {frame_orientation(w, h) for w, h in sizes}
    return "/".join(sorted(kinds)) or "unknown"


def reference_index(t_s: np.ndarray, force_mag: np.ndarray, rule: str, contact_n: float) -> np.ndarray:
    """Pairs that form the zero-force reference: the first one (the paper's rule) or all pairs
    before the first contact (their per-pixel median is taken)."""
    if rule == "first":
        return np.array([0])
    contact = np.flatnonzero(force_mag > contact_n)
    end = contact[0] if len(contact) else len(t_s)
    return np.arange(max(1, end))


def pair_step(frame_period_ns: float, pair_rate_hz: float) -> int:
    """Keep every k-th frame pair so that pairs come at about ``pair_rate_hz`` (0: every pair)."""
    if pair_rate_hz <= 0:
        return 1
    return max(1, int(round(1e9 / pair_rate_hz / frame_period_ns)))


def load_trial(shard: Path, info: dict, sync: dict, force_shift_ns: int = 0) -> dict:
    table = pq.read_table(shard).to_pandas()
    frames = table[table["row"] == "frame"]
    force = table[table["row"] == "force"]
    by_sensor = {s: frames[frames["sensor"] == s].sort_values("t_ns") for s in SENSORS}
    missing = [s for s, f in by_sensor.items() if f.empty]
    if missing:
        raise InputError(shard, f"no frames of {missing}: both fingers are needed")
    left, right = (by_sensor[s]["t_ns"].to_numpy() for s in SENSORS)
    period = np.median(np.diff(left)) if len(left) > 1 else 1e9 / 30
    il, ir = pair_frames(left, right, int(period / 2))
    drops = Counter(info.get("drops", {}))
    drops["unpaired frame"] += (len(left) - len(il)) + (len(right) - len(ir))
    step = pair_step(period, sync["pair_rate_hz"])        # thinned by design: not a drop
    il, ir = il[::step], ir[::step]
    t_ns = (left[il] + right[ir]) // 2
    f_t = force["t_ns"].to_numpy() + force_shift_ns       # the camera's latency (tool/data/session_clock.py)
    order = np.argsort(f_t)
    values, ok = interpolate_at(t_ns.astype(np.float64), f_t[order].astype(np.float64),
                                force[["fx", "fy", "fz"]].to_numpy()[order], sync["max_gap_s"] * 1e9)
    drops["force gap"] += int((~ok).sum())
    stored = table[table["row"] == "reference"].set_index("sensor")["png"]
    ref_png = [stored[s] for s in SENSORS] if set(SENSORS) <= set(stored.index) else None
    return {"info": info, "t_ns": t_ns[ok], "force": values[ok], "drops": drops, "pair_every": step,
            "ref_png": ref_png,
            "png": [by_sensor[SENSORS[0]]["png"].to_numpy()[il[ok]], by_sensor[SENSORS[1]]["png"].to_numpy()[ir[ok]]]}


def bad_zero(force: np.ndarray, normal_sign: float) -> str | None:
    """Why a trial's normal force cannot be right, or None (see the module docstring): it dips
    well below zero after a press (the zero was taken under load), or never rises above zero at
    all (the sign is wrong for this sensor's mounting)."""
    if not len(force):
        return None
    low, high = np.percentile(normal_sign * force[:, 2], [5, 95])
    if low >= -LOADED_START_N:
        return None
    if high < LOADED_START_N:
        return (f"the normal force is negative throughout (5th-95th percentile {low:.2f} to {high:.2f} N): "
                f"tool_sync.normal_sign has the wrong sign for this sensor?")
    return (f"loaded start: the normal force reads {low:.2f} N (5th percentile, below -{LOADED_START_N:g} N), "
            f"so the zero-force offset taken at the start of force.log was under load")


def build_tool_dataset(shards: list[Path], kind: str, out_dir: Path, sync: dict) -> dict:
    trials, dropped, seen = [], [], []
    infos = {Path(shard): read_shard_info(shard) for shard in shards}
    # the camera's latency is the rig's, whatever the trial's kind: every trial of the session tells it
    latencies = camera_latency(list(infos.values()))
    for shard, info in infos.items():
        if info["kind"] != kind:
            continue
        seen.append(info)
        failed = info.get("witness", {}).get("failed")
        if failed:                                # a witness of its labels says they are wrong
            dropped.append({"trial": info["trial"], "source": info["source"],
                            "reason": "; ".join(f"witness '{k}': {v}" for k, v in failed.items())})
            continue
        if info["clock"].get("dropped"):          # ingest could not trust its labels' clock
            dropped.append({"trial": info["trial"], "source": info["source"], "reason": info["clock"]["dropped"]})
            continue
        wrong_clock = lag_outlier(info, latencies, sync["witness"]["max_lag_error_s"]) if "witness" in sync else None
        if wrong_clock:
            dropped.append({"trial": info["trial"], "source": info["source"], "reason": wrong_clock})
            continue
        trials.append(load_trial(shard, info, sync, shift_ns(info, latencies)))
    # frames of every trial are squashed to a square: portrait and landscape trials would put the
    # same contact at different places, so a dataset keeps one orientation
    shapes = {t["info"]["source"]: orientation(t["info"]) for t in trials}
    for source, o in shapes.items():
        if o != next(iter(shapes.values())):
            raise InputError(source, f"frames are {o}, those of {trials[0]['info']['source']} are "
                                     f"{next(iter(shapes.values()))}: one dataset cannot mix frame orientations "
                                     f"(rotate them to one)")
    # every trial against the others of its session: what no named witness catches still stands out
    # (the others are every trial of the session read, left out or not: a rate or a rest level does
    # not depend on the clock fit that left a trial out)
    outliers = session_outliers(seen, sync["witness"]) if "witness" in sync else {}
    standing_out = {seen[i]["source"]: why for i, why in outliers.items()}
    for entry in dropped:                      # left out already: the comparison's finding is added
        if entry["source"] in standing_out:
            entry["reason"] += "; and it " + standing_out[entry["source"]]
    for trial in list(trials):
        why = standing_out.get(trial["info"]["source"])
        if why:
            trials.remove(trial)
            dropped.append({"trial": trial["info"]["trial"], "source": trial["info"]["source"], "reason": why})
    for trial in list(trials):
        wrong = bad_zero(trial["force"], sync["normal_sign"])
        if wrong:
            dropped.append({"trial": trial["info"]["trial"], "source": trial["info"]["source"], "reason": wrong})
            trials.remove(trial)
    if not trials:
        left_out = "; ".join(f"{d['trial']}: {d['reason']}" for d in dropped)
        raise InputError(out_dir, f"no '{kind}' trials among {len(shards)} shards"
                                  + (f" (left out: {left_out})" if left_out else ""))
    size = trials[0]["info"]["image_size"]
    n = sum(len(t["t_ns"]) for t in trials)
    rows, qc = [], []
    out_dir.mkdir(parents=True, exist_ok=True)
    with atomic_path(out_dir / "frames.npy") as tmp_frames, atomic_path(out_dir / "references.npy") as tmp_refs:
        frames = open_memmap(tmp_frames, (n, 2, size, size), np.uint8)
        refs = open_memmap(tmp_refs, (len(trials), 2, size, size), np.uint8)
        k = 0
        for ti, trial in enumerate(trials):
            info, m = trial["info"], len(trial["t_ns"])
            if m == 0:
                raise InputError(info["source"], "no frame pair has a force (all dropped)")
            for s in range(2):
                frames[k:k + m, s] = np.stack([_decode(p, info["source"]) for p in trial["png"][s]])
            fx, fy, fz = trial["force"].T
            normal, shear = sync["normal_sign"] * fz, np.hypot(fx, fy)
            label_mag = normal if kind == "normal" else shear
            ref_idx = reference_index(trial["t_ns"], np.abs(label_mag), sync["reference"], sync["contact_n"])
            if sync["reference"] == "first" and trial["ref_png"] is not None:
                # the format's own zero-force frame (public layout: frame 0, whose label may be dropped)
                refs[ti] = np.stack([_decode(p, info["source"]) for p in trial["ref_png"]])
            else:
                refs[ti] = np.median(frames[k + ref_idx], axis=0).astype(np.uint8) if len(ref_idx) > 1 \
                    else frames[k + ref_idx[0]]
            t_s = (trial["t_ns"] - trial["t_ns"][0]) / 1e9
            rows.append(pd.DataFrame({
                "trial_index": ti, "trial": info["trial"], "tool": info["tool"],
                "orientation_deg": info["orientation_deg"], "insertion_mm": info["insertion_mm"],
                "t_ns": trial["t_ns"], "t_s": t_s, "fx": fx, "fy": fy, "fz": fz,
                "normal": normal, "shear": shear}))
            qc.append({"trial": info["trial"], "tool": info["tool"], "frames": info["frames"], "pairs": m,
                       "pair_every": trial["pair_every"], "drops": dict(trial["drops"]),
                       "clock": {k: v for k, v in info["clock"].items() if k != "curve"},   # curve: in the shard
                       "force_min_n": float(label_mag.min()), "force_max_n": float(label_mag.max()),
                       "reference_frames": int(len(ref_idx)), "source": info["source"],
                       "frame_size": info.get("frame_size", {}),
                       "witness": info.get("witness", {}).get("metrics", {})})
            k += m
        frames.flush()
        refs.flush()
        del frames, refs
    samples = pd.concat(rows, ignore_index=True)
    samples["pose"] = samples["tool"] + "@" + samples["orientation_deg"].round(1).astype(str) + "deg/" + \
        samples["insertion_mm"].round(1).astype(str) + "mm"
    write_parquet(out_dir / "samples.parquet", samples)
    write_json(out_dir / "qc.json", {"kind": kind, "trials": qc, "pairs": int(n), "image_size": size,
                                     "camera_latency": latencies, "dropped_trials": dropped})
    return {"trials": qc, "pairs": n}
