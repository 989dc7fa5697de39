"""Contactile PapillArray messages (driver `papillarray_ros_v2`) and a fast ROS1 codec.

Message definitions follow the vendor driver's msg files (below). Every SensorState that a
hub publishes has the same byte layout (fixed frame_id strings, 9 pillars), so a whole topic is
encoded or decoded at once as a NumPy structured array. Anything that does not fit that layout
is decoded message by message through rosbags, so unusual recordings still read correctly.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from tactilepipe.core.errors import ArgumentError

SENSOR_STATE = "papillarray_ros_v2/msg/SensorState"
PILLAR_STATE = "papillarray_ros_v2/msg/PillarState"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
N_PILLARS = 9

PILLAR_STATE_MSG = """\
Header header
int32 id
float32 dX
float32 dY
float32 dZ
float32 fX
float32 fY
float32 fZ
bool in_contact
int32 slip_state
"""

SENSOR_STATE_MSG = """\
Header header
int64 tus
papillarray_ros_v2/PillarState[] pillars
float32 gfX
float32 gfY
float32 gfZ
float32 gtX
float32 gtY
float32 gtZ
float32 friction_est
float32 target_grip_force
bool is_sd_active
bool is_ref_loaded
bool is_contact
"""

# Pillar layout seen from the sensor face: index = 3*row + col, centre pillar 4 is the tallest.
PILLAR_ROWCOL = np.array([(i // 3, i % 3) for i in range(N_PILLARS)])


def sensor_topic(hub: int, sensor: int) -> str:
    return f"/hub_{hub}/sensor_{sensor}"


@lru_cache(maxsize=1)
def typestore():
    """ROS1 Noetic typestore with the PapillArray messages registered from their .msg text."""
    store = get_typestore(Stores.ROS1_NOETIC)
    types = {}
    types.update(get_types_from_msg(PILLAR_STATE_MSG, PILLAR_STATE))
    types.update(get_types_from_msg(SENSOR_STATE_MSG, SENSOR_STATE))
    store.register(types)
    return store


def _header_fields(prefix: str, frame_id_len: int) -> list:
    fields = [(f"{prefix}seq", "<u4"), (f"{prefix}sec", "<u4"), (f"{prefix}nsec", "<u4"),
              (f"{prefix}fid_len", "<u4")]
    if frame_id_len:
        fields.append((f"{prefix}fid", f"S{frame_id_len}"))
    return fields


@lru_cache(maxsize=16)
def sensor_state_dtype(frame_id_len: int, pillar_frame_id_len: int) -> np.dtype:
    """Packed little-endian layout of one serialised SensorState with 9 pillars."""
    pillar = np.dtype(_header_fields("", pillar_frame_id_len) + [
        ("id", "<i4"), ("d", "<f4", (3,)), ("f", "<f4", (3,)), ("in_contact", "u1"), ("slip_state", "<i4")])
    return np.dtype(_header_fields("", frame_id_len) + [
        ("tus", "<i8"), ("n_pillars", "<u4"), ("pillars", pillar, (N_PILLARS,)),
        ("g", "<f4", (6,)), ("friction_est", "<f4"), ("target_grip_force", "<f4"),
        ("is_sd_active", "u1"), ("is_ref_loaded", "u1"), ("is_contact", "u1")])


@lru_cache(maxsize=16)
def pose_stamped_dtype(frame_id_len: int) -> np.dtype:
    return np.dtype(_header_fields("", frame_id_len) + [("position", "<f8", (3,)), ("orientation", "<f8", (4,))])


def encode_sensor_states(stamp_ns: np.ndarray, tus: np.ndarray, disp: np.ndarray, force: np.ndarray,
                         in_contact: np.ndarray, slip_state: np.ndarray, frame_id: str = "",
                         seq0: int = 0) -> list[bytes]:
    """Serialise a stream of SensorState messages.

    disp, force: (T, 9, 3) in mm and N; in_contact, slip_state: (T, 9). Global forces are the
    sum of the pillars (as the driver computes them) and torques their moments about the centre.
    """
    n = len(stamp_ns)
    fid = frame_id.encode()
    arr = np.zeros(n, dtype=sensor_state_dtype(len(fid), 0))
    arr["seq"] = seq0 + np.arange(n)
    arr["sec"], arr["nsec"] = np.divmod(stamp_ns, 1_000_000_000)
    arr["fid_len"] = len(fid)
    if fid:
        arr["fid"] = fid
    arr["tus"] = tus
    arr["n_pillars"] = N_PILLARS
    p = arr["pillars"]
    p["seq"] = arr["seq"][:, None]
    p["sec"], p["nsec"] = arr["sec"][:, None], arr["nsec"][:, None]
    p["id"] = np.arange(N_PILLARS)
    p["d"], p["f"] = disp, force
    p["in_contact"], p["slip_state"] = in_contact, slip_state
    arr["g"][:, :3] = force.sum(axis=1)
    arr["g"][:, 3:] = global_torques(force)
    arr["is_ref_loaded"] = 1
    arr["is_contact"] = in_contact.any(axis=1)
    raw = arr.tobytes()
    size = arr.dtype.itemsize
    return [raw[i * size:(i + 1) * size] for i in range(n)]


def global_torques(force: np.ndarray, pitch_mm: float = 3.5) -> np.ndarray:
    """Moments (N·mm) of the pillar forces about the sensor centre; force is (..., 9, 3)."""
    x = (PILLAR_ROWCOL[:, 1] - 1) * pitch_mm
    y = (1 - PILLAR_ROWCOL[:, 0]) * pitch_mm
    fx, fy, fz = force[..., 0], force[..., 1], force[..., 2]
    return np.stack([(y * fz).sum(-1), (-x * fz).sum(-1), (x * fy - y * fx).sum(-1)], axis=-1)


def encode_pose_stamped(stamp_ns: np.ndarray, position: np.ndarray, frame_id: str = "base") -> list[bytes]:
    n = len(stamp_ns)
    fid = frame_id.encode()
    arr = np.zeros(n, dtype=pose_stamped_dtype(len(fid)))
    arr["seq"] = np.arange(n)
    arr["sec"], arr["nsec"] = np.divmod(stamp_ns, 1_000_000_000)
    arr["fid_len"] = len(fid)
    if fid:
        arr["fid"] = fid
    arr["position"] = position
    arr["orientation"][:, 3] = 1.0
    raw = arr.tobytes()
    size = arr.dtype.itemsize
    return [raw[i * size:(i + 1) * size] for i in range(n)]


def _string_len_at(raw: bytes, offset: int) -> int:
    return int.from_bytes(raw[offset:offset + 4], "little")


def decode_sensor_states(raws: list[bytes]) -> dict[str, np.ndarray]:
    """Decode serialised SensorStates into arrays: stamp_ns (T,), force/disp (T, 9, 3), ...

    Raises ArgumentError (a ValueError) "record <i>: <problem>" for the first message that cannot
    be decoded; the caller that read the bag names it (shards.read_papillarray_bag: InputError).
    """
    if not raws:
        return _empty_sensor_arrays()
    first = raws[0]
    if len(first) < 16:
        raise ArgumentError("record 0: message shorter than a ROS Header")
    fid_len = _string_len_at(first, 12)
    pillar_off = 16 + fid_len + 8 + 4
    pfid_len = _string_len_at(first, pillar_off + 12) if len(first) >= pillar_off + 16 else 0
    if 16 + fid_len > len(first) or pillar_off + 16 + pfid_len > len(first):
        # a corrupt string length: let the per-message decoder name the bad record
        return _decode_generic(raws)
    dtype = sensor_state_dtype(fid_len, pfid_len)
    size = dtype.itemsize
    if all(len(r) == size for r in raws):
        arr = np.frombuffer(b"".join(raws), dtype=dtype)
        ok = ((arr["fid_len"] == fid_len) & (arr["n_pillars"] == N_PILLARS)
              & (arr["pillars"]["fid_len"] == pfid_len).all(axis=1))
        if ok.all():
            return {
                "stamp_ns": arr["sec"].astype(np.int64) * 1_000_000_000 + arr["nsec"],
                "tus": arr["tus"].astype(np.int64),
                "force": arr["pillars"]["f"].astype(np.float32),
                "disp": arr["pillars"]["d"].astype(np.float32),
                "in_contact": arr["pillars"]["in_contact"].astype(bool),
                "slip_state": arr["pillars"]["slip_state"].astype(np.int32),
                "global": arr["g"].astype(np.float32),
            }
    return _decode_generic(raws)


def _empty_sensor_arrays() -> dict[str, np.ndarray]:
    return {"stamp_ns": np.zeros(0, np.int64), "tus": np.zeros(0, np.int64),
            "force": np.zeros((0, N_PILLARS, 3), np.float32), "disp": np.zeros((0, N_PILLARS, 3), np.float32),
            "in_contact": np.zeros((0, N_PILLARS), bool), "slip_state": np.zeros((0, N_PILLARS), np.int32),
            "global": np.zeros((0, 6), np.float32)}


def _ros1_sec(sec: int) -> int:
    """ROS1 time is uint32 seconds; rosbags reads them as int32 (negative after January 2038)."""
    return int(sec) & 0xFFFF_FFFF


def _decode_generic(raws: list[bytes]) -> dict[str, np.ndarray]:
    store = typestore()
    out = {k: [] for k in _empty_sensor_arrays()}
    for i, raw in enumerate(raws):
        try:
            msg = store.deserialize_ros1(raw, SENSOR_STATE)
        except Exception as exc:  # rosbags raises several types for malformed bytes
            raise ArgumentError(f"record {i}: cannot decode SensorState ({type(exc).__name__}: {exc})") from None
        if len(msg.pillars) != N_PILLARS:
            raise ArgumentError(f"record {i}: SensorState has {len(msg.pillars)} pillars, expected {N_PILLARS}")
        out["stamp_ns"].append(_ros1_sec(msg.header.stamp.sec) * 1_000_000_000 + msg.header.stamp.nanosec)
        out["tus"].append(msg.tus)
        out["force"].append([(p.fX, p.fY, p.fZ) for p in msg.pillars])
        out["disp"].append([(p.dX, p.dY, p.dZ) for p in msg.pillars])
        out["in_contact"].append([p.in_contact for p in msg.pillars])
        out["slip_state"].append([p.slip_state for p in msg.pillars])
        out["global"].append((msg.gfX, msg.gfY, msg.gfZ, msg.gtX, msg.gtY, msg.gtZ))
    empty = _empty_sensor_arrays()
    return {k: np.asarray(v, dtype=empty[k].dtype).reshape((-1,) + empty[k].shape[1:]) for k, v in out.items()}


def decode_pose_stamped(raws: list[bytes]) -> tuple[np.ndarray, np.ndarray]:
    """Return (stamp_ns (T,), position (T, 3)) of PoseStamped messages; ArgumentError
    "record <i>: <problem>" for the first message that cannot be decoded."""
    if not raws:
        return np.zeros(0, np.int64), np.zeros((0, 3))
    fid_len = _string_len_at(raws[0], 12) if len(raws[0]) >= 16 else -1
    dtype = pose_stamped_dtype(fid_len) if 0 <= fid_len <= len(raws[0]) else None
    if dtype is not None and all(len(r) == dtype.itemsize for r in raws):
        arr = np.frombuffer(b"".join(raws), dtype=dtype)
        return arr["sec"].astype(np.int64) * 1_000_000_000 + arr["nsec"], arr["position"].copy()
    store = typestore()
    stamps, pos = [], []
    for i, raw in enumerate(raws):
        try:
            msg = store.deserialize_ros1(raw, POSE_STAMPED)
        except Exception as exc:
            raise ArgumentError(f"record {i}: cannot decode PoseStamped ({type(exc).__name__}: {exc})") from None
        stamps.append(_ros1_sec(msg.header.stamp.sec) * 1_000_000_000 + msg.header.stamp.nanosec)
        pos.append((msg.pose.position.x, msg.pose.position.y, msg.pose.position.z))
    return np.asarray(stamps, np.int64), np.asarray(pos, float)
