"""A ROS bag writer for tests: a tool trial as a ROS1 bag or a ROS2 bag (sqlite3 or mcap), with
raw or compressed images, to feed the reader (tactilepipe.tool.formats.rosbag) real bags."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from typing import Mapping

import cv2
import numpy as np

from tactilepipe.core.atomic import atomic_path, remove_stale_temporaries
from tactilepipe.core.errors import ArgumentError
from tactilepipe.tool.formats.raw import SENSORS
from tactilepipe.tool.formats.rosbag import (COMPRESSED_IMAGE, DEFAULT_TOPICS, ENCODING_CHANNELS, IMAGE, NS,
                                             WRENCH_KEY, WRENCH_STAMPED, _typestore)

FORMATS = ("ros1", "ros2_sqlite3", "ros2_mcap")
SENSOR_ARGS = {"digit_left": "frames_left", "digit_right": "frames_right"}   # write_ros_trial's argument names
ROS2_BAG_VERSION = 8          # oldest rosbag2 metadata version rosbags writes (8 or 9)

def _serialize(ros2: bool, msg, msgtype: str) -> bytes:
    store = _typestore(ros2)
    raw = store.serialize_cdr(msg, msgtype) if ros2 else store.serialize_ros1(msg, msgtype)
    return bytes(raw)


def _header(ros2: bool, stamp_ns: int, frame_id: str, seq: int):
    t = _typestore(ros2).types
    stamp = t["builtin_interfaces/msg/Time"](sec=int(stamp_ns // NS), nanosec=int(stamp_ns % NS))
    if ros2:
        return t["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)
    return t["std_msgs/msg/Header"](seq=seq, stamp=stamp, frame_id=frame_id)


def _image_messages(ros2: bool, frames, stamps: np.ndarray, frame_id: str, compressed: bool,
                    codec: str, encoding: str, jpeg_quality: int) -> tuple[str, list[bytes]]:
    t = _typestore(ros2).types
    arg = SENSOR_ARGS.get(frame_id, frame_id)
    out = []
    for i, (img, stamp) in enumerate(zip(frames, stamps)):
        img = np.asarray(img)
        if img.dtype != np.uint8 or not (img.ndim == 3 and img.shape[2] == 3 or img.ndim == 2):
            raise ArgumentError(f"{arg} frame {i}: expected BGR uint8 H x W x 3 (or H x W gray), "
                                f"got {img.dtype} {img.shape}")
        if img.ndim == 2:
            img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
        header = _header(ros2, int(stamp), frame_id, i)
        if compressed:
            ext, params = (".png", []) if codec == "png" else (".jpg", [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality])
            ok, buf = cv2.imencode(ext, img, params)
            if not ok:
                raise ArgumentError(f"{arg} frame {i}: cv2 could not encode {codec}")
            msg = t[COMPRESSED_IMAGE](header=header, format=codec, data=buf.reshape(-1))
            out.append(_serialize(ros2, msg, COMPRESSED_IMAGE))
        else:
            if encoding == "bgr8":
                pix = img
            elif encoding == "rgb8":
                pix = img[..., ::-1]
            else:
                pix = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
            pix = np.ascontiguousarray(pix)
            h, w = pix.shape[:2]
            msg = t[IMAGE](header=header, height=h, width=w, encoding=encoding, is_bigendian=0,
                           step=w * ENCODING_CHANNELS[encoding], data=pix.reshape(-1))
            out.append(_serialize(ros2, msg, IMAGE))
    return (COMPRESSED_IMAGE if compressed else IMAGE), out


def _wrench_messages(ros2: bool, stamps: np.ndarray, force: np.ndarray, frame_id: str) -> list[bytes]:
    t = _typestore(ros2).types
    vec, wrench = t["geometry_msgs/msg/Vector3"], t["geometry_msgs/msg/Wrench"]
    out = []
    for i, (stamp, f) in enumerate(zip(stamps, force)):
        msg = t[WRENCH_STAMPED](header=_header(ros2, int(stamp), frame_id, i),
                                wrench=wrench(force=vec(x=float(f[0]), y=float(f[1]), z=float(f[2])),
                                              torque=vec(x=0.0, y=0.0, z=0.0)))
        out.append(_serialize(ros2, msg, WRENCH_STAMPED))
    return out


def _write_bag(target: Path, fmt: str, streams: list[tuple[str, str, np.ndarray, list[bytes]]]) -> None:
    """Write ``[(topic, msgtype, receive stamps, raws)]`` in time order, atomically."""
    events = sorted(((int(t), k, i) for k, (_, _, stamps, _) in enumerate(streams) for i, t in enumerate(stamps)))
    if fmt == "ros1":
        from rosbags.rosbag1 import Writer
        store = _typestore(False)
        with atomic_path(target) as tmp:
            tmp.unlink()  # rosbags refuses to overwrite
            with Writer(tmp) as writer:
                conns = [writer.add_connection(topic, msgtype, typestore=store) for topic, msgtype, _, _ in streams]
                for stamp, k, i in events:
                    writer.write(conns[k], stamp, streams[k][3][i])
        return
    from rosbags.rosbag2 import StoragePlugin, Writer
    plugin = StoragePlugin.SQLITE3 if fmt == "ros2_sqlite3" else StoragePlugin.MCAP
    store = _typestore(True)
    target.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(target)
    work = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent))
    try:
        bagdir = work / target.name          # storage files are named after the bag directory
        with Writer(bagdir, version=ROS2_BAG_VERSION, storage_plugin=plugin) as writer:
            conns = [writer.add_connection(topic, msgtype, typestore=store) for topic, msgtype, _, _ in streams]
            for stamp, k, i in events:
                writer.write(conns[k], stamp, streams[k][3][i])
        if target.exists() or target.is_symlink():
            os.replace(target, work / ".previous")
        os.replace(bagdir, target)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def write_ros_trial(path: str | Path, frames_left, frames_right, frame_host_ns, force_host_ns, force_n,
                    fmt: str, compressed: bool, topics: Mapping[str, str] = DEFAULT_TOPICS, *,
                    codec: str = "png", encoding: str = "bgr8", jpeg_quality: int = 95) -> Path:
    """Write a trial as a ROS bag (atomically; an existing bag at ``path`` is replaced).

    frames_left / frames_right: sequences (or N x H x W x 3 arrays) of BGR uint8 frames; None
    leaves that sensor out. frame_host_ns: one array of stamps shared by both sensors, or a
    ``{sensor: stamps}`` dict / ``(left, right)`` pair when their counts or times differ.
    force_host_ns (m,), force_n (m, 3) in N. fmt: "ros1" (a file, conventionally ``.bag``),
    "ros2_sqlite3" or "ros2_mcap" (a bag directory). compressed: CompressedImage with ``codec``
    "png" (lossless) or "jpeg", else Image with ``encoding`` bgr8, rgb8 or mono8 (converted from
    BGR). Header stamps and receive times are the given host_ns. Returns the bag path.
    """
    if fmt not in FORMATS:
        raise ArgumentError(f"fmt must be one of {FORMATS}, got {fmt!r}")
    if compressed and codec not in ("png", "jpeg"):
        raise ArgumentError(f"codec must be png or jpeg, got {codec!r}")
    if not compressed and encoding not in ENCODING_CHANNELS:
        raise ArgumentError(f"encoding must be one of {tuple(ENCODING_CHANNELS)}, got {encoding!r}")
    ros2 = fmt != "ros1"
    given = {"digit_left": frames_left, "digit_right": frames_right}
    given = {k: v for k, v in given.items() if v is not None}
    if not given:
        raise ArgumentError("at least one of frames_left, frames_right is needed")
    if isinstance(frame_host_ns, Mapping):
        stamps_of = {k: frame_host_ns[k] for k in given}
    elif isinstance(frame_host_ns, tuple) and len(frame_host_ns) == 2:
        stamps_of = {k: frame_host_ns[SENSORS.index(k)] for k in given}
    else:
        stamps_of = {k: frame_host_ns for k in given}
    streams = []
    for key, frames in given.items():
        if key not in topics:
            raise ArgumentError(f"topics: no topic configured for {key}: {dict(topics)}")
        stamps = np.asarray(stamps_of[key], np.int64)
        if len(stamps) != len(frames):
            raise ArgumentError(f"{key}: {len(frames)} frames but {len(stamps)} stamps "
                                f"({SENSOR_ARGS[key]} against frame_host_ns)")
        msgtype, raws = _image_messages(ros2, frames, stamps, key, compressed, codec, encoding, jpeg_quality)
        streams.append((topics[key], msgtype, stamps, raws))
    force_ns = np.asarray(force_host_ns, np.int64)
    force = np.asarray(force_n, np.float64)
    if force.shape != (len(force_ns), 3):
        raise ArgumentError(f"force_n must be ({len(force_ns)}, 3) (a row per force_host_ns stamp), "
                            f"got {force.shape}")
    streams.append((topics[WRENCH_KEY], WRENCH_STAMPED, force_ns, _wrench_messages(ros2, force_ns, force, "nano17")))
    path = Path(path)
    _write_bag(path, fmt, streams)
    return path
