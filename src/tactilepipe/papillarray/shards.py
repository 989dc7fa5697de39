"""PapillArray bag -> one Parquet shard (one row per message), validated on the way in.

Shard columns: topic, stamp_ns, sensor (0/1, null on pose rows), global gfx..gtz, per pillar
f{x,y,z}{i}, d{x,y,z}{i}, contact{i}, and tool_z (m, null on sensor rows; from the optional
arm pose topic).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa_
import pyarrow.parquet as pq

from tactilepipe.papillarray import messages as pa
from tactilepipe.core.atomic import atomic_path
from tactilepipe.papillarray.bagio import read_topics
from tactilepipe.core.errors import InputError

GLOBAL_COLS = ["gfx", "gfy", "gfz", "gtx", "gty", "gtz"]
AXES = "xyz"
DEFAULT_POSE_TOPIC = "/tool_pose"
# Plausibility bounds, orders of magnitude beyond what a PapillArray can measure (a pillar
# deflects about 2 mm under tens of N). ROS1 bags carry no checksums: a corrupted float usually
# lands far outside these bounds (a flipped exponent bit), which is how it is caught.
MAX_ABS_FORCE_N = 1000.0
MAX_ABS_DISP_MM = 100.0


def sensor_topics(hub: int = 0) -> dict[str, int]:
    return {pa.sensor_topic(hub, s): s for s in (0, 1)}


def _check_stream(path: Path, topic: str, dec: dict) -> None:
    bad = ~np.isfinite(dec["force"]).all(axis=(1, 2)) | ~np.isfinite(dec["global"]).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(path, "force values are NaN or inf", f"{topic} message {i}")
    wild = ((np.abs(dec["force"]) > MAX_ABS_FORCE_N).any(axis=(1, 2))
            | (np.abs(dec["global"][:, :3]) > MAX_ABS_FORCE_N).any(axis=1)
            | ~np.isfinite(dec["disp"]).all(axis=(1, 2)) | (np.abs(dec["disp"]) > MAX_ABS_DISP_MM).any(axis=(1, 2)))
    if wild.any():
        i = int(np.argmax(wild))
        raise InputError(path, f"implausible values (|force| > {MAX_ABS_FORCE_N:g} N or |displacement| > "
                               f"{MAX_ABS_DISP_MM:g} mm, or non-finite displacement): a corrupt message?",
                         f"{topic} message {i}")
    steps = np.diff(dec["stamp_ns"])
    if (steps <= 0).any():
        i = int(np.argmax(steps <= 0)) + 1
        kind = "duplicated" if steps[i - 1] == 0 else "out-of-order"
        raise InputError(path, f"{kind} header timestamp", f"{topic} message {i}")


def _decode_error(path: Path, topic: str, exc: ValueError) -> InputError:
    """InputError naming the bag and the message of a decoder's "record <i>: <problem>"."""
    record, sep, problem = str(exc).partition(": ")
    if sep and record.startswith("record "):
        return InputError(path, problem, f"{topic} {record}")
    return InputError(path, str(exc), topic)


def check_sensor_spans(path: Path, sensors: dict, max_offset_s: float) -> None:
    """InputError when the two sensors' header stamps do not cover the same span (their first or
    last stamps differ by more than ``max_offset_s``): the driver publishes both sensors in one
    loop, so a sensor whose stamps start or end elsewhere is on another clock, or lost part of the
    recording. Its readings would be paired with the other sensor's at other times, in silence."""
    if len(sensors) < 2:
        return
    first = {s: int(dec["stamp_ns"][0]) for s, dec in sensors.items() if len(dec["stamp_ns"])}
    last = {s: int(dec["stamp_ns"][-1]) for s, dec in sensors.items() if len(dec["stamp_ns"])}
    if len(first) < 2:
        return
    ref = first[min(first)]
    start_off, end_off = (first[1] - first[0]) / 1e9, (last[1] - last[0]) / 1e9
    if max(abs(start_off), abs(end_off)) > max_offset_s:
        spans = " and ".join(f"sensor {s} {(first[s] - ref) / 1e9:.3f}-{(last[s] - ref) / 1e9:.3f} s"
                             for s in sorted(first))
        raise InputError(path, f"the two sensors do not cover the same span ({spans}, from sensor 0's first "
                               f"stamp): sensor 1 starts {start_off:+.3f} s and ends {end_off:+.3f} s from "
                               f"sensor 0, more than papillarray_ingest.max_span_offset_s {max_offset_s:g} s. "
                               f"A sensor on another clock, or one that stopped publishing?")


def read_papillarray_bag(path: str | Path, hub: int = 0, pose_topic: str = DEFAULT_POSE_TOPIC) -> dict:
    """Decode a bag into {"sensors": {0: arrays, 1: arrays}, "pose": (stamps, z) or None}."""
    path = Path(path)
    topics = sensor_topics(hub)
    wanted = {t: pa.SENSOR_STATE for t in topics} | {pose_topic: pa.POSE_STAMPED}
    raw = read_topics(path, wanted)
    found = [t for t in topics if t in raw and raw[t][1]]
    if not found:
        raise InputError(path, f"no PapillArray messages: expected topics {sorted(topics)} "
                               f"of type {pa.SENSOR_STATE}")
    sensors = {}
    for topic in found:
        try:
            dec = pa.decode_sensor_states(raw[topic][1])
        except ValueError as exc:         # ArgumentError "record <i>: ..." (or numpy's on odd bytes)
            raise _decode_error(path, topic, exc) from None
        _check_stream(path, topic, dec)
        sensors[topics[topic]] = dec
    pose = None
    if pose_topic in raw and raw[pose_topic][1]:
        try:
            stamps, pos = pa.decode_pose_stamped(raw[pose_topic][1])
        except ValueError as exc:
            raise _decode_error(path, pose_topic, exc) from None
        if not np.isfinite(pos).all():
            raise InputError(path, "pose contains NaN or inf", pose_topic)
        pose = (stamps, pos[:, 2])
    return {"sensors": sensors, "pose": pose}


def shard_table(decoded: dict) -> pa_.Table:
    columns: dict[str, list] = {}
    parts = []
    for sensor, dec in sorted(decoded["sensors"].items()):
        n = len(dec["stamp_ns"])
        cols = {"topic": np.full(n, pa.sensor_topic(0, sensor)), "stamp_ns": dec["stamp_ns"],
                "sensor": np.full(n, sensor, np.int8)}
        for j, name in enumerate(GLOBAL_COLS):
            cols[name] = dec["global"][:, j]
        for i in range(pa.N_PILLARS):
            for j, ax in enumerate(AXES):
                cols[f"f{ax}{i}"] = dec["force"][:, i, j]
            for j, ax in enumerate(AXES):
                cols[f"d{ax}{i}"] = dec["disp"][:, i, j]
            cols[f"contact{i}"] = dec["in_contact"][:, i]
            cols[f"slip{i}"] = dec["slip_state"][:, i]
        parts.append(cols)
    if decoded["pose"] is not None:
        stamps, z = decoded["pose"]
        parts.append({"topic": np.full(len(stamps), DEFAULT_POSE_TOPIC), "stamp_ns": stamps, "tool_z": z})
    names = list(parts[0]) + ["tool_z"]
    types = {"tool_z": pa_.float64()}
    for part in parts:
        for name, values in part.items():
            types.setdefault(name, pa_.array(values[:0]).type)
    for name in names:
        # rows of another topic hold nulls in this topic's columns (and tool_z is all null
        # in recordings without the arm pose)
        columns[name] = pa_.concat_arrays([
            pa_.array(part[name], type=types[name]) if name in part
            else pa_.nulls(len(part["stamp_ns"]), type=types[name]) for part in parts])
    return pa_.table(columns)


def ingest_bag(bag: str | Path, shard: str | Path, hub: int = 0, pose_topic: str = DEFAULT_POSE_TOPIC,
               max_span_offset_s: float | None = None) -> dict:
    """Validate and convert one bag into one Parquet shard (written atomically); returns counts.
    With ``max_span_offset_s`` (the stages pass params.yaml papillarray_ingest's), a bag whose two
    sensors' spans differ by more is refused (check_sensor_spans)."""
    decoded = read_papillarray_bag(bag, hub, pose_topic)
    if max_span_offset_s is not None:
        check_sensor_spans(Path(bag), decoded["sensors"], max_span_offset_s)
    table = shard_table(decoded)
    with atomic_path(shard) as tmp:
        pq.write_table(table, tmp, compression="zstd")
    return {"bag": str(bag), "messages": table.num_rows,
            "sensors": sorted(decoded["sensors"]), "pose": decoded["pose"] is not None}
