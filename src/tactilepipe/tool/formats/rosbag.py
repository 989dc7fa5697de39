"""Tool-force trials recorded as ROS bags (ROS1 ``.bag``, ROS2 sqlite3 or mcap) -> RawTrial.

A recording has one image topic per DIGIT (``sensor_msgs/Image`` with encoding bgr8, rgb8 or
mono8, or ``sensor_msgs/CompressedImage`` holding jpeg/png) and the Nano17 as
``geometry_msgs/WrenchStamped``. Every topic is stamped by the same ROS clock, so the header
stamps (not the bag's receive times) are the host clock of the RawTrial and no offset is needed.

The bag is read once; image messages are kept serialised (raw bytes) and a frame is only decoded
when ``SensorFrames.load(i)`` asks for it. The wrench is decoded while reading. Torques are not
part of a RawTrial and are ignored. Grasp metadata is not in a bag: the caller passes it, usually
from a sidecar ``<bag stem>.meta.json`` next to the bag (``read_sidecar_meta``).

Formats: a ROS1 bag is a file (``#ROSBAG V2.0``); a ROS2 bag is a directory with
``metadata.yaml`` (sqlite3 or mcap storage); a bare ``.db3`` or ``.mcap`` storage file also reads.
"""

from __future__ import annotations

import json
from dataclasses import asdict
from functools import lru_cache
from pathlib import Path
from typing import Mapping, Sequence

import cv2
import numpy as np
from rosbags.typesys import Stores, get_typestore

from tactilepipe.core.errors import ArgumentError, InputError
from tactilepipe.core.rawfile import BAG_MAX, META_MAX, check_raw_file, read_raw_text
from tactilepipe.tool.formats.imagefile import decode
from tactilepipe.tool.formats.native_layout import TrialMeta
from tactilepipe.tool.formats.raw import SENSORS, RawTrial, SensorFrames

WRENCH_KEY = "wrench"
DEFAULT_TOPICS: dict[str, str] = {
    "digit_left": "/digit_left/image_raw",
    "digit_right": "/digit_right/image_raw",
    WRENCH_KEY: "/nano17/wrench",
}
IMAGE = "sensor_msgs/msg/Image"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"
ENCODING_CHANNELS = {"bgr8": 3, "rgb8": 3, "mono8": 1}
CLOCK = {"method": "ros_header_stamps", "offset_s": 0.0}
ROS1_MAGIC = b"#ROSBAG V2.0"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
JPEG_MAGIC = b"\xff\xd8\xff"
NS = 1_000_000_000


# ------------------------------------------------------------------------------------------------
# typestores and message helpers

@lru_cache(maxsize=2)
def _typestore(ros2: bool):
    return get_typestore(Stores.ROS2_HUMBLE if ros2 else Stores.ROS1_NOETIC)


def _deserialize(ros2: bool, raw: bytes, msgtype: str):
    store = _typestore(ros2)
    return store.deserialize_cdr(raw, msgtype) if ros2 else store.deserialize_ros1(raw, msgtype)



def _stamp_ns(msg) -> int:
    return int(msg.header.stamp.sec) * NS + int(msg.header.stamp.nanosec)


def _record(topic: str, index: int) -> str:
    return f"{topic} message {index}"


# ------------------------------------------------------------------------------------------------
# metadata

def sidecar_path(bag_path: str | Path) -> Path:
    """``<bag stem>.meta.json`` next to the bag (for a ROS2 bag directory: ``<dir name>.meta.json``)."""
    p = Path(bag_path)
    stem = p.name if p.is_dir() else p.stem
    return p.with_name(f"{stem}.meta.json")


def _bag_stem(path: Path) -> str:
    return path.name if path.is_dir() else path.stem


def _check_meta(where: str | Path, meta: Mapping, default_trial: str) -> dict:
    """Validate trial metadata with the keys of TrialMeta; ``trial`` defaults to ``default_trial``."""
    raw = meta if isinstance(meta, TrialMeta) else (dict(meta) if isinstance(meta, Mapping) else meta)
    return asdict(TrialMeta.from_dict(raw, where, default_trial))


def read_sidecar_meta(bag_path: str | Path) -> dict:
    """Trial metadata of a bag from ``<bag stem>.meta.json`` (keys of TrialMeta, validated).

    ``trial`` may be left out of the sidecar: it then defaults to the bag's stem.
    """
    path = sidecar_path(bag_path)
    try:
        raw = json.loads(read_raw_text(path, META_MAX, "bag's metadata sidecar"))
    except FileNotFoundError:
        raise InputError(path, "missing: a ROS bag trial needs a metadata sidecar next to "
                               f"{Path(bag_path).name}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(path, f"not valid JSON: {exc}") from None
    return _check_meta(path, raw, _bag_stem(Path(bag_path)))


def _check_topics(topics: Mapping[str, str]) -> tuple[list[str], str]:
    sensors = [k for k in topics if k != WRENCH_KEY]
    unknown = set(sensors) - set(SENSORS)
    if unknown or not sensors or WRENCH_KEY not in topics:
        raise ArgumentError(f"topics (params.yaml tool_ingest.ros_topics) must map '{WRENCH_KEY}' and one or both "
                            f"of {SENSORS} to topic names, got {dict(topics)}")
    names = [topics[k] for k in topics]
    if len(set(names)) != len(names):
        raise ArgumentError(f"topics (params.yaml tool_ingest.ros_topics): topic names must be distinct, "
                            f"got {dict(topics)}")
    return sensors, topics[WRENCH_KEY]


# ------------------------------------------------------------------------------------------------
# reading

def _bag_kind(path: Path) -> str:
    """'ros1' or 'ros2' (directory with metadata.yaml, or a bare .db3/.mcap file)."""
    if not path.exists():
        raise InputError(path, "bag not found")
    if path.is_dir():
        if not (path / "metadata.yaml").is_file():
            raise InputError(path, "directory is not a ROS2 bag (no metadata.yaml)")
        return "ros2"
    if check_raw_file(path, BAG_MAX, "ROS bag") == 0:
        raise InputError(path, "bag file is empty")
    if path.suffix in (".db3", ".mcap"):
        return "ros2"
    with open(path, "rb") as fh:
        head = fh.read(len(ROS1_MAGIC))
    if path.suffix == ".bag" or head == ROS1_MAGIC:
        return "ros1"
    raise InputError(path, "not a ROS bag: expected a ROS1 .bag file, a ROS2 bag directory "
                           "(metadata.yaml) or a .db3/.mcap storage file")


def _read_messages(path: Path, kind: str, wanted: Sequence[str]
                   ) -> tuple[dict[str, str], dict[str, str], dict[str, list[bytes]]]:
    """Read the raw messages of the wanted topics: (all topics -> type, wanted -> type, wanted -> raws).

    Wanted topics absent from the bag are absent from the result; only a damaged bag is an error.
    """
    if kind == "ros1":
        from rosbags.rosbag1 import Reader
    else:
        from rosbags.rosbag2 import Reader
    found: dict[str, str] = {}
    types: dict[str, str] = {}
    raws: dict[str, list[bytes]] = {}
    try:
        with Reader(path) as reader:
            conns = []
            for conn in reader.connections:
                found.setdefault(conn.topic, conn.msgtype)
                if conn.topic not in wanted:
                    continue
                if conn.topic in types and types[conn.topic] != conn.msgtype:
                    raise InputError(path, f"topic {conn.topic} has connections of types "
                                           f"{types[conn.topic]} and {conn.msgtype}")
                fmt = getattr(getattr(conn, "ext", None), "serialization_format", "cdr" if kind == "ros2" else None)
                if kind == "ros2" and fmt != "cdr":
                    raise InputError(path, f"topic {conn.topic} is serialised as {fmt!r}, only cdr is supported")
                types[conn.topic] = conn.msgtype
                raws.setdefault(conn.topic, [])
                conns.append(conn)
            if conns:
                for conn, _, raw in reader.messages(connections=conns):
                    raws[conn.topic].append(bytes(raw))
    except InputError:
        raise
    except Exception as exc:  # rosbags ReaderError, sqlite3/struct/IO/zstd errors of damaged bags
        what = "ROS1 bag" if kind == "ros1" else "ROS2 bag"
        raise InputError(path, f"cannot read {what} (truncated or corrupt?): {type(exc).__name__}: {exc}") from None
    return found, types, raws


def _describe_topics(found: Mapping[str, str]) -> str:
    if not found:
        return "the bag has no topics"
    return "topics found: " + ", ".join(f"{t} ({found[t]})" for t in sorted(found))


def _check_stamps(path: Path, topic: str, stamps: np.ndarray) -> None:
    if len(stamps) > 1:
        bad = np.diff(stamps) <= 0
        if bad.any():
            k = int(np.argmax(bad)) + 1
            what = "duplicates" if stamps[k] == stamps[k - 1] else "goes back from"
            raise InputError(path, f"header stamp {stamps[k]} ns {what} {stamps[k - 1]} ns of the previous "
                                   "message: stamps must increase", _record(topic, k))


def _compressed_codec(fmt: str, data: bytes) -> str | None:
    """'png' or 'jpeg' from the magic bytes, if the format string allows it; else None."""
    fmt = fmt.lower()
    if data.startswith(PNG_MAGIC):
        codec = "png"
    elif data.startswith(JPEG_MAGIC):
        codec = "jpeg"
    else:
        return None
    names = {"png": ("png",), "jpeg": ("jpeg", "jpg")}[codec]
    if fmt and not any(n in fmt for n in names):
        return None
    return codec


def _index_images(path: Path, ros2: bool, topic: str, msgtype: str, raws: list[bytes]) -> np.ndarray:
    """Validate every image message of a topic (without decoding pixels); return header stamps."""
    stamps = np.empty(len(raws), np.int64)
    for i, raw in enumerate(raws):
        try:
            msg = _deserialize(ros2, raw, msgtype)
        except Exception as exc:
            raise InputError(path, f"cannot decode {msgtype}: {type(exc).__name__}: {exc}", _record(topic, i)) from None
        stamps[i] = _stamp_ns(msg)
        if msgtype == IMAGE:
            enc = msg.encoding
            if enc not in ENCODING_CHANNELS:
                raise InputError(path, f"unsupported image encoding {enc!r} (supported: "
                                       f"{', '.join(ENCODING_CHANNELS)})", _record(topic, i))
            h, w, step, n = int(msg.height), int(msg.width), int(msg.step), len(msg.data)
            if h <= 0 or w <= 0:
                raise InputError(path, f"image is {w}x{h} pixels", _record(topic, i))
            if step < w * ENCODING_CHANNELS[enc]:
                raise InputError(path, f"step {step} is shorter than a row of {w} {enc} pixels", _record(topic, i))
            if n != h * step:
                raise InputError(path, f"image data has {n} bytes, expected height*step = {h}*{step} = {h * step}",
                                 _record(topic, i))
        else:
            data = bytes(msg.data[:16])
            if _compressed_codec(msg.format, data) is None:
                raise InputError(path, f"compressed image is not readable png/jpeg data (format {msg.format!r}, "
                                       f"{len(msg.data)} bytes)", _record(topic, i))
    return stamps


def _frame_loader(path: Path, ros2: bool, topic: str, msgtype: str, raws: list[bytes]):
    """load(i): decode message i of the topic into a BGR uint8 H x W x 3 array."""

    def load(i: int) -> np.ndarray:
        index = range(len(raws))[i]            # IndexError for bad i, negative i like a list
        try:
            msg = _deserialize(ros2, raws[index], msgtype)
        except Exception as exc:
            raise InputError(path, f"cannot decode {msgtype}: {type(exc).__name__}: {exc}",
                             _record(topic, index)) from None
        if msgtype == IMAGE:
            h, w, step, enc = int(msg.height), int(msg.width), int(msg.step), msg.encoding
            ch = ENCODING_CHANNELS[enc]
            rows = np.asarray(msg.data, np.uint8).reshape(h, step)[:, :w * ch].reshape(h, w, ch)
            if enc == "bgr8":
                return rows.copy()
            if enc == "rgb8":
                return np.ascontiguousarray(rows[..., ::-1])
            return np.repeat(rows, 3, axis=2)
        data = np.asarray(msg.data, np.uint8)
        try:
            img, warning = decode(data, cv2.IMREAD_COLOR)
        except cv2.error as exc:
            img, why = None, str(exc).strip().splitlines()[-1]
        else:
            why = "cv2.imdecode failed"
            if warning:
                img, why = None, f"corrupt image data: the decoder warned {warning!r}"
        if img is None or img.ndim != 3 or img.shape[2] != 3:
            raise InputError(path, f"cannot decode compressed image (format {msg.format!r}, {len(data)} bytes): {why}",
                             _record(topic, index))
        return img

    return load


def _decode_wrench(path: Path, ros2: bool, topic: str, raws: list[bytes]) -> tuple[np.ndarray, np.ndarray]:
    stamps = np.empty(len(raws), np.int64)
    force = np.empty((len(raws), 3), np.float64)
    for i, raw in enumerate(raws):
        try:
            msg = _deserialize(ros2, raw, WRENCH_STAMPED)
        except Exception as exc:
            raise InputError(path, f"cannot decode {WRENCH_STAMPED}: {type(exc).__name__}: {exc}",
                             _record(topic, i)) from None
        stamps[i] = _stamp_ns(msg)
        f = msg.wrench.force
        force[i] = (f.x, f.y, f.z)
    if not np.isfinite(force).all():
        k = int(np.argmax(~np.isfinite(force).all(axis=1)))
        raise InputError(path, f"force contains NaN or inf: {force[k].tolist()}", _record(topic, k))
    return stamps, force


def read_ros_trial(path: str | Path, meta: Mapping | TrialMeta,
                   topics: Mapping[str, str] = DEFAULT_TOPICS) -> RawTrial:
    """Read one trial from a ROS1 bag, a ROS2 bag directory (sqlite3/mcap) or a .db3/.mcap file.

    meta: tool, kind, orientation_deg, insertion_mm (and optionally trial, default the bag stem)
    as in TrialMeta, e.g. from ``read_sidecar_meta(path)``. topics: ``{"digit_left": topic,
    "digit_right": topic, "wrench": topic}``; leave a sensor out for a single-sensor recording.
    Every configured topic must be in the bag, non-empty, of a supported type, with strictly
    increasing header stamps; anything else raises InputError naming the bag (topic, message).
    """
    path = Path(path)
    sensors, wrench_topic = _check_topics(topics)
    kind = _bag_kind(path)
    meta = _check_meta(path, meta, _bag_stem(path))
    ros2 = kind == "ros2"
    wanted = [topics[k] for k in topics]
    found, types, raws = _read_messages(path, kind, wanted)

    for key in sensors:
        topic = topics[key]
        if topic not in types:
            raise InputError(path, f"image topic {topic} ({key}) is not in the bag; {_describe_topics(found)}")
        if types[topic] not in (IMAGE, COMPRESSED_IMAGE):
            raise InputError(path, f"topic {topic} ({key}) has type {types[topic]}, expected {IMAGE} or "
                                   f"{COMPRESSED_IMAGE}")
    if wrench_topic not in types:
        raise InputError(path, f"wrench topic {wrench_topic} is not in the bag; {_describe_topics(found)}")
    if types[wrench_topic] != WRENCH_STAMPED:
        raise InputError(path, f"topic {wrench_topic} (wrench) has type {types[wrench_topic]}, "
                               f"expected {WRENCH_STAMPED}")
    for key in [*sensors, WRENCH_KEY]:
        if not raws[topics[key]]:
            raise InputError(path, f"topic {topics[key]} ({key}) has no messages")

    frames: dict[str, SensorFrames] = {}
    for key in sensors:
        topic, msgtype = topics[key], types[topics[key]]
        stamps = _index_images(path, ros2, topic, msgtype, raws[topic])
        _check_stamps(path, topic, stamps)
        frames[key] = SensorFrames(host_ns=stamps, load=_frame_loader(path, ros2, topic, msgtype, raws[topic]),
                                   source=[f"{path} [{_record(topic, i)}]" for i in range(len(stamps))])
    force_ns, force_n = _decode_wrench(path, ros2, wrench_topic, raws[wrench_topic])
    _check_stamps(path, wrench_topic, force_ns)

    return RawTrial(trial=meta["trial"], tool=meta["tool"], kind=meta["kind"],
                    orientation_deg=float(meta["orientation_deg"]), insertion_mm=float(meta["insertion_mm"]),
                    frames=frames, force_host_ns=force_ns, force_n=force_n, clock=dict(CLOCK), drops={},
                    source=str(path))
