"""Shards -> the off-table force samples of every lift (the table every model reads).

A lift is off the table while the arm is raised (pose topic) or, in recordings without the
pose topic, while the vertical shear |Fy| carried by the pads stays near its hold level. Either
way the pads must carry a load off the table: a lift whose vertical shear never rises clearly
above the noise (nothing grasped) is refused, never kept with its volume label. So is a bag that
is not one whole lift (volume/whole_lift.py): one that starts after lift-off, ends before the
put-down, or holds a second lift.

Axes (docs/robustness.md): on both sensors +z points into the pad (grip: Fz > 0) and +y down
along the pad (the container's weight: Fy > 0 off the table); +x completes a right-handed frame,
so it is mirrored between the two facing sensors. params.yaml `papillarray_axes` maps a sensor
mounted or configured otherwise onto these; a lift whose Fy is clearly negative off the table,
or whose grip Fz is, on a sensor is refused naming it (a reversed axis), never kept with negative
loads.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from tactilepipe.core.errors import InputError
from tactilepipe.volume import whole_lift, witness
from tactilepipe.volume.whole_lift import fill_short_gaps

FORCE_COLS = ["gfx", "gfy", "gfz"]
PILLAR_LOADED_N = 0.2        # N: a pillar pressing harder than this carries load
SLIPPING_SHARE = 0.5         # of the loaded pillars of a pad flagged slipping (slip_state != 0): the pad slides
SLIP_HOLD_S = 0.2            # s: sliding that long, off the table, is a grasp that slipped
MAX_POSE_RISE_M = 2.0        # m: a UR arm reaches 0.5-1.3 m; study 001 lifts by 0.10 m


def read_shard(path: str | Path) -> dict:
    """Global forces per sensor on sensor 0's clock, plus the tool height when recorded."""
    path = Path(path)
    slip_cols = [f"{c}{i}" for c in ("fz", "slip") for i in range(9)]
    try:
        shard = pq.ParquetFile(path)                # one open: the schema says which slip columns exist
        table = shard.read(columns=["topic", "stamp_ns", "sensor", *FORCE_COLS, "tool_z",
                                    *(c for c in slip_cols if c in shard.schema_arrow.names)])
    except Exception as exc:
        raise InputError(path, f"cannot read shard: {type(exc).__name__}: {exc}") from None
    df = table.to_pandas()
    sensors = df[df["sensor"].notna()]
    if sensors.empty:
        raise InputError(path, "shard holds no sensor messages")
    by_sensor = {int(s): g for s, g in sensors.groupby("sensor")}
    if 0 not in by_sensor:
        raise InputError(path, "shard has no /hub_0/sensor_0 messages (the reference clock)")
    if 1 not in by_sensor:      # else its forces would be NaN, and so every feature of volume_sensor 1
        raise InputError(path, "shard has no /hub_0/sensor_1 messages: a lift is read on both pads (the grip, the "
                               "load and volume_sensor)")
    t_ns = by_sensor[0]["stamp_ns"].to_numpy()
    out = {"t": (t_ns - t_ns[0]) / 1e9, "stamp_ns": t_ns}
    for s in (0, 1):
        g = by_sensor.get(s)
        for c in FORCE_COLS:
            if g is None:
                out[f"{c[1:]}{s}"] = np.full(len(t_ns), np.nan)
            else:  # sensor 1 is put on sensor 0's stamps (the driver publishes both together)
                out[f"{c[1:]}{s}"] = np.interp(t_ns, g["stamp_ns"].to_numpy(), g[c].to_numpy(np.float64))
        out[f"slipping{s}"] = (np.interp(t_ns, g["stamp_ns"].to_numpy(), _slipping_share(g))
                               if g is not None and "slip0" in g else np.zeros(len(t_ns)))
    pose = df[df["tool_z"].notna()]
    out["tool_z"] = (np.interp(t_ns, pose["stamp_ns"].to_numpy(), pose["tool_z"].to_numpy())
                     if len(pose) >= 2 else None)
    return out


def _slipping_share(g: pd.DataFrame) -> np.ndarray:
    """Per sample, the share of a pad's loaded pillars whose slip_state flags them slipping."""
    fz = g[[f"fz{i}" for i in range(9)]].to_numpy(np.float64)
    slip = g[[f"slip{i}" for i in range(9)]].to_numpy() != 0
    loaded = fz > PILLAR_LOADED_N
    return (slip & loaded).sum(axis=1) / np.maximum(loaded.sum(axis=1), 1)


def sustained_slip(rec: dict, start: int, stop: int) -> float:
    """Longest time (s) off the table during which either pad slid (most of its loaded pillars
    flagged slipping): the grasp did not hold the container, so its forces do not weigh it."""
    sliding = (np.maximum(rec["slipping0"], rec["slipping1"])[start:stop] >= SLIPPING_SHARE)
    a, b = _longest_run(sliding)
    return float(rec["t"][start + b - 1] - rec["t"][start + a]) if b > a else 0.0


def _longest_run(mask: np.ndarray) -> tuple[int, int]:
    """[start, stop) of the longest run of True values (0, 0 when there is none)."""
    if not mask.any():
        return 0, 0
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    k = int(np.argmax(stops - starts))
    return int(starts[k]), int(stops[k])


def apply_axes(rec: dict, axes: dict) -> dict:
    """``rec`` with each sensor's fx, fy, fz taken from the recorded axis (and sign) that
    params.yaml ``papillarray_axes`` names for it ({"sensor_0": {"x": "+x", "y": "-y", ...}})."""
    out = dict(rec)
    for s in (0, 1):
        for axis, source in axes[f"sensor_{s}"].items():
            out[f"f{axis}{s}"] = (-1.0 if source[0] == "-" else 1.0) * rec[f"f{source[1]}{s}"]
    return out


def _vertical_load(rec: dict, seg: dict) -> tuple[np.ndarray, float, int]:
    """Smoothed vertical shear |Fy0| + |Fy1| above its level at rest (the first samples, on the
    table), the noise of that smoothed signal at rest, and the smoothing width (samples). Each
    sensor counts by its magnitude, so a reversed axis is found by its sign (_check_fy_sign)
    instead of cancelling the load and reading as a lift that never left the table."""
    dt = np.median(np.diff(rec["t"])) if len(rec["t"]) > 1 else 1.0
    fy = np.abs(np.nan_to_num(rec["fy0"])) + np.abs(np.nan_to_num(rec["fy1"]))
    width = max(1, int(round(seg["force_smooth_s"] / dt)))
    smooth = np.convolve(fy, np.ones(width) / width, mode="same")
    rest = np.median(smooth[: max(1, width * 2)])
    noise = np.std(fy[: max(2, width * 2)]) / np.sqrt(width)   # of the smoothed signal at rest
    return smooth - rest, float(noise), width


def off_table_segment(rec: dict, seg: dict, path: str | Path = "?") -> tuple[int, int, str]:
    """Sample range [start, stop) when the container is off the table, and the method used.

    Either method needs the pads to carry a load clearly above the noise (10 x the noise of the
    smoothed vertical shear at rest) off the table: a lift with nothing grasped is an InputError
    (the force method finds no off-table phase, the pose method finds one that carries nothing).
    So is a bag that is not one whole lift (whole_lift.py: named before "never leaves the table",
    which a bag that starts after lift-off would otherwise read as).
    """
    method = seg["method"]
    if method == "pose" and rec["tool_z"] is None:
        raise InputError(path, "segment.method is 'pose' but the bag has no /tool_pose topic")
    load, noise, width = _vertical_load(rec, seg)
    whole_lift.check_starts_on_table(rec, width, path)     # else its load reads as none: "never leaves the table"
    if method in ("auto", "pose") and rec["tool_z"] is not None:
        z = rec["tool_z"]
        rest = np.median(z[: max(1, int(0.1 * len(z)))])
        rise = float(np.nanmax(z) - rest)
        if not rise <= MAX_POSE_RISE_M:
            raise InputError(path, f"/tool_pose rises {rise:.4g} above its rest height: more than an arm reaches "
                                   f"({MAX_POSE_RISE_M:g} m). The pose must be in metres (millimetres?)")
        mask = (z - rest) * 1000.0 > seg["pose_lift_threshold_mm"]
        used = "pose"
    else:
        level = np.percentile(load, 75)
        if level < 10 * noise:
            mask = np.zeros(len(load), bool)            # no load rises clearly above the noise
        else:
            mask = load >= seg["force_fraction"] * level
            mask = fill_short_gaps(mask, 2 * width)     # noise dips on light loads split the hold
        used = "force"
    start, stop = _longest_run(mask)
    duration = rec["t"][stop - 1] - rec["t"][start] if stop > start else 0.0
    if duration < seg["min_off_table_s"]:
        raise InputError(path, f"the lift never leaves the table (longest off-table phase {duration:.2f} s "
                               f"by the {used} method, need {seg['min_off_table_s']} s)")
    if used == "pose":      # the force method found its phase by the load; the arm rises without one
        carried = float(np.median(load[start:stop]))
        if not carried > 10 * noise:
            raise InputError(path, f"the pads carry no load off the table (median vertical shear {carried:.3f} N "
                                   f"above rest over the {duration:.2f}-s off-table phase by the pose method, "
                                   f"need 10 x the rest noise {noise:.3f} N): nothing grasped?")
    whole_lift.check_one_lift(rec, seg, load, mask, used, start, stop, width, path)
    _check_fy_sign(rec, start, stop, width, noise, path)
    _check_fz_sign(rec, start, stop, noise, path)
    return start, stop, used


def session_lifts(sessions: list[str], raw_root: Path, shard_root: Path) -> pd.DataFrame:
    """One row per lift of the sessions (lift, session, volume_ml, set, shard, labels: the lifts.csv),
    from each session's lifts.csv; the shard of raw_root/<session>/<bag> is shard_root/<session>/<bag stem>.parquet."""
    from tactilepipe.volume.labels import read_session_labels
    rows = []
    for session in sessions:
        for row in read_session_labels(Path(raw_root) / session):
            stem = Path(row["bag"]).stem
            rows.append({"lift": f"{session}/{stem}", "session": session, "volume_ml": row["volume_ml"],
                         "set": row["set"], "shard": str(Path(shard_root) / session / f"{stem}.parquet"),
                         "labels": str(Path(raw_root) / session / "lifts.csv")})
    return pd.DataFrame(rows)


def _wrong_sign(rec: dict, axis: str, start: int, stop: int, noise: float, rest: int | None) -> list[str]:
    """Each sensor whose median ``axis`` force off the table is clearly negative (10 x the rest
    noise): measured above its level at rest (the first ``rest`` samples), or against zero."""
    wrong = []
    for s in (0, 1):
        f = rec[f"f{axis}{s}"]
        if not np.isfinite(f).any():
            continue
        level = float(np.median(f[start:stop]) - (np.median(f[:rest]) if rest else 0.0))
        if level < -10 * noise:
            wrong.append(f"sensor {s} (F{axis} {level:+.3f} N)")
    return wrong


def _check_fy_sign(rec: dict, start: int, stop: int, width: int, noise: float, path) -> None:
    """InputError naming each sensor whose Fy is clearly negative off the table (see the module
    docstring: the container's weight reads Fy > 0 on both)."""
    wrong = _wrong_sign(rec, "y", start, stop, noise, rest=max(2, width * 2))
    if wrong:
        raise InputError(path, f"Fy has the wrong sign while the container is lifted on {' and '.join(wrong)}: "
                               f"its weight must read Fy > 0 (docs/robustness.md); a reversed y axis? Map it in "
                               f"params.yaml papillarray_axes (e.g. y: '-y')")


def _check_fz_sign(rec: dict, start: int, stop: int, noise: float, path) -> None:
    """InputError naming each sensor whose grip force Fz is clearly negative off the table: the
    pads squeeze the container, which reads Fz > 0 on both (a grip that holds the container up
    cannot be a pull). Against zero, not above rest: the grip may already be closed at rest."""
    wrong = _wrong_sign(rec, "z", start, stop, noise, rest=None)
    if wrong:
        raise InputError(path, f"the grip force Fz has the wrong sign while the container is lifted on "
                               f"{' and '.join(wrong)}: a grip must read Fz > 0 (docs/robustness.md); a reversed "
                               f"z axis? Map it in params.yaml papillarray_axes (e.g. z: '-z')")


def build_dataset(lifts: pd.DataFrame, seg: dict, axes: dict, checks: dict) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Off-table samples of every lift, and a QC row per lift.

    Left out of the samples, each named in its QC row: a lift whose grasp slid for SLIP_HOLD_S or
    longer off the table (the pads' slip flags; ``slipped``, with the time it slid, ``slip_s``),
    and a lift whose sensors stand out from its session's (``stands_out``, with the evidence;
    volume/witness.py). The labels of the lifts kept are then checked against their carried load
    over each session (``label_check``); a label the load contradicts is an InputError.

    lifts: columns lift (unique id), session, volume_ml, set, shard (path), and optionally labels
    (the session's lifts.csv, named by a label error); axes: params.yaml papillarray_axes; checks:
    params.yaml volume_checks.
    """
    parts, qc = {}, []
    for row in lifts.itertuples(index=False):
        rec = apply_axes(read_shard(row.shard), axes)
        start, stop, used = off_table_segment(rec, seg, row.shard)
        slid = sustained_slip(rec, start, stop)
        dt = np.median(np.diff(rec["t"])) if len(rec["t"]) > 1 else 1.0
        rest = max(2, 2 * max(1, int(round(seg["force_smooth_s"] / dt))))    # as _vertical_load's rest
        part = pd.DataFrame({k: rec[k][start:stop] for k in ("t", "fx0", "fy0", "fz0", "fx1", "fy1", "fz1")})
        for i, (name, value) in enumerate([("lift", row.lift), ("session", row.session),
                                           ("volume_ml", row.volume_ml), ("set", row.set)]):
            part.insert(i, name, value)
        parts[row.lift] = part
        qc.append({"lift": row.lift, "session": row.session, "volume_ml": row.volume_ml, "set": row.set,
                   "samples": len(rec["t"]), "off_table_samples": stop - start,
                   "off_table_s": float(rec["t"][stop - 1] - rec["t"][start]), "segment_method": used,
                   "mean_fy0": float(part["fy0"].mean()), "mean_fz0": float(part["fz0"].mean()),
                   "slip_s": slid, "slipped": slid >= SLIP_HOLD_S,
                   **witness.lift_evidence(rec, start, stop, rest)})
    qc = pd.DataFrame(qc)
    qc["stands_out"], qc["label_check"] = "", "not checked: slipped or stands out"
    sources = (lifts.set_index("lift")["labels"] if "labels" in lifts else lifts.set_index("lift")["shard"])
    for session, rows in qc.groupby("session", sort=False):
        held = rows[~rows["slipped"]]
        if len(held) >= checks["min_session_lifts"]:
            for lift, evidence in witness.standing_out(held, checks).items():
                qc.loc[qc["lift"] == lift, "stands_out"] = evidence
        kept = qc.loc[(qc["session"] == session) & ~qc["slipped"] & (qc["stands_out"] == "")]
        if len(kept):
            qc.loc[kept.index, "label_check"] = witness.check_labels(kept, checks, sources[kept["lift"].iloc[0]])
    keep = ~qc["slipped"] & (qc["stands_out"] == "")
    if not keep.any():
        raise InputError(lifts["shard"].iloc[0], f"no lift is left: {int(qc['slipped'].sum())} slid off the table "
                                                 f"(longest slides {qc['slip_s'].min():.2f}-{qc['slip_s'].max():.2f} "
                                                 f"s), {int((qc['stands_out'] != '').sum())} stand out from their "
                                                 f"session. If these grasps held, the sensor's slip_state uses a "
                                                 f"non-zero code for not slipping (docs/papillarray.md)")
    return pd.concat([parts[lift] for lift in qc.loc[keep, "lift"]], ignore_index=True), qc
