"""The bad-input corpus: every reader fed broken recordings, generated here from good ones.

Each case builds one broken input and names what the reader must say. The rule for every case:
an InputError (ConfigError for parameters) whose message starts with the file (and names the
record where there is one) and states the problem; never a library's exception; no output and no
temporary left behind. Where the rule is to drop and count (garbled serial lines, public frames
below 0 N), the count must reach the shard's QC record instead.

The test ids read as the list of cases: `pytest tests/robustness/test_corpus.py --collect-only -q`.
"""

from __future__ import annotations

import json
import re
import shutil
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import cv2
import numpy as np
import pytest
import yaml

from support import ros_writer
from tactilepipe.papillarray import messages as pa
from tactilepipe.core.config import load_params
from tactilepipe.core.errors import ConfigError, InputError
from tactilepipe.papillarray.shards import ingest_bag
from tactilepipe.tool.formats import rosbag as ri
from tactilepipe.tool.data.dataset import build_tool_dataset
from tactilepipe.tool.formats.trials import open_trial
from tactilepipe.tool.data.ingest import ingest_trial, read_shard_info
from tactilepipe.tool.formats.native_layout import FRAME_H, FRAME_W
from tactilepipe.drift.recordings import recording_reading
from tactilepipe.volume.dataset import read_shard
from tactilepipe.volume.labels import read_session_labels

from support.bags import sensor_stream, write_ros1_bag
from support.sessions import (INGEST, N_FRAMES, SIZE, START_NS, SYNC, digit_frame, make_native_session,
                              make_public_session, noisy, serial_lines, write_ros, write_serial)
from support.project import REPO


# --- good inputs the cases break: tests/support/sessions.py ---------------------------------------

@pytest.fixture(scope="module")
def goods(tmp_path_factory, sim_lifts) -> dict:
    root = tmp_path_factory.mktemp("good")
    g = {"native": make_native_session(root), "public": make_public_session(root), "bag": sim_lifts[1]["bag"],
         "shard": sim_lifts[1]["shard"]}
    for fmt in ros_writer.FORMATS:
        g[fmt] = write_ros(root / fmt / ("trial.bag" if fmt == "ros1" else "trial"), fmt)
    return g


@dataclass
class Case:
    """A reader call on a broken input and what its error must say."""
    run: Callable[[], object]
    path: Path | str                   # the file the message must start with
    problem: str                       # regex of the problem
    record: str | None = None          # regex of the record, where there is one
    error: type = InputError


class Ctx:
    def __init__(self, tmp: Path, goods: dict):
        self.tmp, self.goods = tmp, goods
        self.out = tmp / "out"
        self.out.mkdir()

    def copy(self, key: str) -> Path:
        src = self.goods[key]
        dst = self.tmp / "in" / src.name
        dst.parent.mkdir(parents=True, exist_ok=True)
        (shutil.copytree if src.is_dir() else shutil.copy)(src, dst)
        if key in ros_writer.FORMATS:
            shutil.copy(ri.sidecar_path(src), ri.sidecar_path(dst))
        return dst

    # readers, each writing its output into self.out
    def native(self, trial: Path):
        return lambda: ingest_trial(open_trial(trial, "native"), self.out / "s.parquet", SIZE, INGEST)

    def public(self, trial: Path):
        return lambda: ingest_trial(open_trial(trial, "public"), self.out / "s.parquet", SIZE, INGEST)

    def ros(self, bag: Path):
        return lambda: ingest_trial(open_trial(bag, "ros"), self.out / "s.parquet", SIZE, INGEST)

    def papillarray(self, bag: Path):
        return lambda: ingest_bag(bag, self.out / "s.parquet")


def overwrite(path: Path, offset_fraction: float, n: int = 4096, seed: int = 1, skip: int = 0) -> None:
    raw = bytearray(path.read_bytes())
    at = int(len(raw) * offset_fraction) + skip
    raw[at:at + n] = np.random.default_rng(seed).bytes(len(raw[at:at + n]))
    path.write_bytes(bytes(raw))


def truncate(path: Path, keep: float) -> None:
    path.write_bytes(path.read_bytes()[:int(path.stat().st_size * keep)])


def ros_storage(bag: Path) -> Path:
    return bag if bag.is_file() else next(p for p in bag.iterdir() if p.suffix in (".db3", ".mcap"))


# --- the cases ------------------------------------------------------------------------------------

CASES: dict[str, Callable[[Ctx], Case]] = {}


def case(name: str):
    def register(fn):
        assert name not in CASES, name
        CASES[name] = fn
        return fn
    return register


# PapillArray ROS1 bags (volume and drift scenes) -> shards.ingest_bag

def _papill_bag(c: Ctx, name: str, mutate=None, n: int = 30, sensors=(0, 1), msgtype=pa.SENSOR_STATE) -> Path:
    s = sensor_stream(n=n, seed=3)
    header = s["stamp_ns"].copy()
    force = s["force"].copy()
    raws_of = {}
    for k in sensors:
        raws_of[k] = pa.encode_sensor_states(header, s["tus"], s["disp"], force, s["in_contact"], s["slip_state"])
    if mutate:
        mutate(s, header, force, raws_of)
    topics = {pa.sensor_topic(0, k): (msgtype if k == sensors[0] else pa.SENSOR_STATE, s["stamp_ns"].tolist(),
                                      raws_of[k]) for k in sensors}
    return write_ros1_bag(c.tmp / "in" / f"{name}.bag", topics)


@case("ros1_papillarray/truncated_half")
def _(c):
    bag = c.copy("bag"); truncate(bag, 0.5)
    return Case(c.papillarray(bag), bag, "cannot read ROS1 bag")


@case("ros1_papillarray/truncated_last_bytes")
def _(c):
    bag = c.copy("bag"); truncate(bag, 0.999)
    return Case(c.papillarray(bag), bag, "cannot read ROS1 bag")


@case("ros1_papillarray/empty_file")
def _(c):
    bag = c.copy("bag"); bag.write_bytes(b"")
    return Case(c.papillarray(bag), bag, "bag file is empty")


@case("ros1_papillarray/magic_only")
def _(c):
    bag = c.copy("bag"); bag.write_bytes(b"#ROSBAG V2.0\n")
    return Case(c.papillarray(bag), bag, "cannot read ROS1 bag")


@case("ros1_papillarray/random_bytes")
def _(c):
    bag = c.copy("bag"); bag.write_bytes(np.random.default_rng(5).bytes(30000))
    return Case(c.papillarray(bag), bag, "cannot read ROS1 bag")


@case("ros1_papillarray/overwritten_middle")
def _(c):
    bag = c.copy("bag"); overwrite(bag, 0.5)
    return Case(c.papillarray(bag), bag, "cannot read ROS1 bag|cannot decode")


@case("ros1_papillarray/overwritten_index")
def _(c):
    bag = c.copy("bag"); overwrite(bag, 0.98, n=2000)
    return Case(c.papillarray(bag), bag, "cannot read ROS1 bag")


@case("ros1_papillarray/wrong_message_type")
def _(c):
    store = pa.typestore()
    raws = [bytes(store.serialize_ros1(store.types["std_msgs/msg/String"](data="x"), "std_msgs/msg/String"))] * 3
    bag = write_ros1_bag(c.tmp / "in" / "t.bag", {"/hub_0/sensor_0": ("std_msgs/msg/String", [1, 2, 3], raws)})
    return Case(c.papillarray(bag), bag, "topic /hub_0/sensor_0 has type std_msgs/msg/String, expected "
                                         "papillarray_ros_v2/msg/SensorState")


@case("ros1_papillarray/duplicated_timestamp")
def _(c):
    def mutate(s, header, force, raws):
        header[12] = header[11]
        raws[0] = pa.encode_sensor_states(header, s["tus"], s["disp"], force, s["in_contact"], s["slip_state"])
    bag = _papill_bag(c, "dup", mutate, sensors=(0,))
    return Case(c.papillarray(bag), bag, "duplicated header timestamp", r"/hub_0/sensor_0 message 12")


@case("ros1_papillarray/out_of_order_timestamp")
def _(c):
    def mutate(s, header, force, raws):
        header[[20, 21]] = header[[21, 20]]
        raws[1] = pa.encode_sensor_states(header, s["tus"], s["disp"], force, s["in_contact"], s["slip_state"])
    bag = _papill_bag(c, "ooo", mutate)
    return Case(c.papillarray(bag), bag, "out-of-order header timestamp", r"/hub_0/sensor_1 message 21")


@case("ros1_papillarray/nan_force")
def _(c):
    def mutate(s, header, force, raws):
        force[7, 4, 2] = np.nan
        raws[0] = pa.encode_sensor_states(header, s["tus"], s["disp"], force, s["in_contact"], s["slip_state"])
    bag = _papill_bag(c, "nan", mutate, sensors=(0,))
    return Case(c.papillarray(bag), bag, "force values are NaN or inf", r"/hub_0/sensor_0 message 7")


@case("ros1_papillarray/corrupt_float_exponent")
def _(c):
    """A flipped exponent bit in a pillar force (ROS1 has no checksum): caught by the plausibility bound."""
    def mutate(s, header, force, raws):
        dtype = pa.sensor_state_dtype(0, 0)
        off = dtype.fields["pillars"][1] + dtype["pillars"].base.fields["f"][1] + 4 * 2   # pillar 0, fZ
        raw = bytearray(raws[0][9])
        (value,) = struct.unpack_from("<f", raw, off)
        struct.pack_into("<I", raw, off, struct.unpack("<I", struct.pack("<f", value))[0] ^ (1 << 30))
        raws[0][9] = bytes(raw)
    bag = _papill_bag(c, "flip", mutate, sensors=(0,))
    return Case(c.papillarray(bag), bag, "implausible values|NaN or inf", r"/hub_0/sensor_0 message 9")


@case("ros1_papillarray/truncated_message")
def _(c):
    def mutate(s, header, force, raws):
        raws[0][5] = raws[0][5][:-40]
    bag = _papill_bag(c, "short", mutate, sensors=(0,))
    return Case(c.papillarray(bag), bag, "cannot decode SensorState", r"/hub_0/sensor_0 record 5")


@case("ros1_papillarray/other_message_definition")
def _(c):
    """Recorded with another SensorState definition (no tus, float64 globals): named field by field,
    before any message is decoded by the vendor's layout."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    store = get_typestore(Stores.ROS1_NOETIC)
    other = pa.SENSOR_STATE_MSG.replace("int64 tus\n", "").replace("float32 gf", "float64 gf")
    store.register({**get_types_from_msg(pa.PILLAR_STATE_MSG, pa.PILLAR_STATE),
                    **get_types_from_msg(other, pa.SENSOR_STATE)})
    st = sensor_stream(n=5, seed=3)
    raws = pa.encode_sensor_states(st["stamp_ns"], st["tus"], st["disp"], st["force"], st["in_contact"],
                                   st["slip_state"])
    bag = c.tmp / "in" / "other.bag"
    bag.parent.mkdir(parents=True, exist_ok=True)
    with Writer(bag) as writer:
        conn = writer.add_connection("/hub_0/sensor_0", pa.SENSOR_STATE, typestore=store)
        for t, raw in zip(st["stamp_ns"], raws):
            writer.write(conn, int(t), raw)
    return Case(c.papillarray(bag), bag, r"topic /hub_0/sensor_0: the bag's definition of "
                                         r"papillarray_ros_v2/msg/SensorState differs from the driver's: "
                                         r"field tus missing; field gfX is float64, expected float32")


@case("ros1_papillarray/missing_file")
def _(c):
    bag = c.tmp / "in" / "nope.bag"
    return Case(c.papillarray(bag), bag, "bag file not found")


# Tool trials as ROS1 / ROS2 sqlite3 / ROS2 mcap bags -> rosbag_import + ingest

for _fmt in ros_writer.FORMATS:
    @case(f"{_fmt}_tool/truncated")
    def _(c, fmt=_fmt):
        bag = c.copy(fmt); truncate(ros_storage(bag), 0.6)
        return Case(c.ros(bag), bag, "cannot read ROS[12] bag")

    @case(f"{_fmt}_tool/empty_storage_file")
    def _(c, fmt=_fmt):
        bag = c.copy(fmt); ros_storage(bag).write_bytes(b"")
        return Case(c.ros(bag), bag, "bag file is empty|cannot read ROS2 bag")

    @case(f"{_fmt}_tool/overwritten_records")
    def _(c, fmt=_fmt):
        # headers, schemas and connection records near the start (pixels overwritten further on
        # go unnoticed: no checksums; see docs/robustness.md)
        bag = c.copy(fmt); overwrite(ros_storage(bag), 0.0, n=2000, skip=16)
        return Case(c.ros(bag), bag, "cannot read ROS[12] bag|cannot decode")

    @case(f"{_fmt}_tool/all_black_frame")
    def _(c, fmt=_fmt):
        frames = [digit_frame(i, 48, 64) for i in range(8)]
        frames[3] = np.zeros_like(frames[3])
        bag = write_ros(c.tmp / "in" / ("b.bag" if fmt == "ros1" else "b"), fmt, left=frames, right=frames[::-1])
        return Case(c.ros(bag), bag, "digit_left: frame is all black", r"/digit_left/image_raw message 3")

    @case(f"{_fmt}_tool/saturated_frame")
    def _(c, fmt=_fmt):
        frames = [digit_frame(i, 48, 64) for i in range(8)]
        right = [f.copy() for f in frames]
        right[5][:] = 255
        bag = write_ros(c.tmp / "in" / ("s.bag" if fmt == "ros1" else "s"), fmt, left=frames, right=right)
        return Case(c.ros(bag), bag, "digit_right: frame is saturated", r"/digit_right/image_raw message 5")

    @case(f"{_fmt}_tool/frame_size_changes")
    def _(c, fmt=_fmt):
        frames = [digit_frame(i, 48, 64) for i in range(8)]
        frames[6] = digit_frame(6, 40, 64)
        bag = write_ros(c.tmp / "in" / ("z.bag" if fmt == "ros1" else "z"), fmt, left=frames, right=frames)
        return Case(c.ros(bag), bag, "frame is 64x40, the sensor's first frame is 64x48",
                    r"/digit_left/image_raw message 6")

    @case(f"{_fmt}_tool/nan_force")
    def _(c, fmt=_fmt):
        force = np.zeros((16, 3))
        force[4, 2] = np.nan
        bag = write_ros(c.tmp / "in" / ("n.bag" if fmt == "ros1" else "n"), fmt, force=force)
        return Case(c.ros(bag), bag, "force contains NaN or inf", r"/nano17/wrench message 4")


@case("ros1_tool/missing_sidecar")
def _(c):
    bag = c.copy("ros1"); ri.sidecar_path(bag).unlink()
    return Case(c.ros(bag), ri.sidecar_path(bag), "missing: a ROS bag trial needs a metadata sidecar")


@case("ros1_tool/sidecar_wrong_type")
def _(c):
    bag = c.copy("ros1")
    ri.sidecar_path(bag).write_text(json.dumps({"tool": "k", "kind": "normal", "orientation_deg": "five",
                                                "insertion_mm": 1}))
    return Case(c.ros(bag), ri.sidecar_path(bag), "orientation_deg must be a finite number")


@case("ros2_sqlite3_tool/no_metadata_yaml")
def _(c):
    bag = c.copy("ros2_sqlite3"); (bag / "metadata.yaml").unlink()
    return Case(c.ros(bag), bag, "not a ROS2 bag|no metadata.yaml")


@case("ros2_mcap_tool/metadata_yaml_garbage")
def _(c):
    bag = c.copy("ros2_mcap"); (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: [unclosed\n")
    return Case(c.ros(bag), bag, "cannot read ROS2 bag")


# The rig's native layout -> native_import + ingest

def _native(c: Ctx) -> Path:
    session = c.copy("native")
    return session / "t00"


def _png(trial: Path, sensor: str = "digit_left", i: int = 3) -> Path:
    return trial / sensor / f"frame_{i:06d}.png"


IMAGE_CASES = {
    "unreadable": (lambda p: p.write_bytes(b"\x89PNG\r\n\x1a\n garbage"), "unreadable or missing image"),
    "empty_file": (lambda p: p.write_bytes(b""), "unreadable or missing image"),
    "wrong_size": (lambda p: cv2.imwrite(str(p), digit_frame(0, FRAME_W, FRAME_H)),
                   "frame is 320x240, the sensor's first frame is 240x320"),
    "not_a_digit_resolution": (lambda p: cv2.imwrite(str(p), digit_frame(0, 100, 100)), "not a DIGIT resolution"),
    "truncated_png": (lambda p: p.write_bytes(p.read_bytes()[:len(p.read_bytes()) // 2]), "truncated PNG"),
    "grayscale": (lambda p: cv2.imwrite(str(p), digit_frame(0)[..., 0]), "grayscale image"),
    "four_channels": (lambda p: cv2.imwrite(str(p), cv2.cvtColor(digit_frame(0), cv2.COLOR_BGR2BGRA)),
                      "expected 3-channel uint8 BGR, got 4 channels"),
    "sixteen_bit": (lambda p: cv2.imwrite(str(p), digit_frame(0).astype(np.uint16) * 256),
                    "expected 3-channel uint8 BGR, got 3 channels of uint16"),
    "all_black": (lambda p: cv2.imwrite(str(p), np.zeros((FRAME_H, FRAME_W, 3), np.uint8)), "frame is all black"),
    "nearly_black_noise": (lambda p: cv2.imwrite(str(p), np.random.default_rng(0).integers(
        0, 8, (FRAME_H, FRAME_W, 3)).astype(np.uint8)), "frame is all black"),
    "saturated": (lambda p: cv2.imwrite(str(p), np.full((FRAME_H, FRAME_W, 3), 255, np.uint8)), "frame is saturated"),
    "missing": (lambda p: p.unlink(), "files are missing"),
}
for _name, (_break, _problem) in IMAGE_CASES.items():
    @case(f"native_image/{_name}")
    def _(c, brk=_break, problem=_problem):
        trial = _native(c)
        brk(_png(trial))
        return Case(c.native(trial), _png(trial), problem)


FRAMES_CSV_CASES = {
    "missing": (None, "missing: every sensor folder needs frames.csv", None),
    "bad_header": ("frame;host_ns\n0;1\n", "header must be 'frame,host_ns'", "line 1"),
    "non_numeric": ("frame,host_ns\n0,100\n1,abc\n", "expected 'frame,host_ns' integers", "line 3"),
    "wrong_columns": ("frame,host_ns\n0,100,7\n", "expected 'frame,host_ns' integers", "line 2"),
    "frame_number_twice": ("frame,host_ns\n0,100\n1,150\n1,200\n", "frame number 1 listed twice", "line 4"),
    "frame_number_back": ("frame,host_ns\n0,100\n2,200\n1,300\n", r"frame number 1 out of order \(after 2\)",
                          "line 4"),
    "duplicated_timestamp": ("frame,host_ns\n0,100\n1,100\n", "do not increase", "line 3"),
    "out_of_order_timestamp": ("frame,host_ns\n0,100\n1,300\n2,200\n", "do not increase", "line 4"),
    "garbage_bytes": (b"frame,host_ns\n0,100\n1,\xff\xfe\n", "non-ASCII byte 0xff", "line 3"),
    "timestamp_overflows_int64": ("frame,host_ns\n0,99999999999999999999\n", "does not fit in 64 bits", "line 2"),
    "underscore_digits": ("frame,host_ns\n0,1_000\n", "expected 'frame,host_ns' integers", "line 2"),
    "header_only": ("frame,host_ns\n", "no frames", None),
}
for _name, (_text, _problem, _record) in FRAMES_CSV_CASES.items():
    @case(f"native_frames_csv/{_name}")
    def _(c, text=_text, problem=_problem, record=_record):
        trial = _native(c)
        path = trial / "digit_right" / "frames.csv"
        if text is None:
            path.unlink()
        else:
            path.write_bytes(text if isinstance(text, bytes) else text.encode())
        return Case(c.native(trial), path, problem, record)


META_CASES = {
    "missing": (None, "missing: every trial needs meta.json"),
    "not_json": ("{tool: knife", "not valid JSON"),
    "not_utf8": (b'{"tool": "\xff"}', "not valid JSON"),
    "not_an_object": ("[1, 2]", "must be a JSON object"),
    "missing_key": (json.dumps({"trial": "t", "tool": "k", "kind": "normal", "orientation_deg": 1}),
                    r"missing keys \['insertion_mm'\]"),
    "unknown_key": (json.dumps({"trial": "t", "tool": "k", "kind": "normal", "orientation_deg": 1,
                                "insertion_mm": 2, "grip": 3}), r"unknown keys \['grip'\]"),
    "wrong_type": (json.dumps({"trial": "t", "tool": "k", "kind": "normal", "orientation_deg": "5",
                               "insertion_mm": 2}), "orientation_deg must be a finite number"),
    "bool_for_number": (json.dumps({"trial": "t", "tool": "k", "kind": "normal", "orientation_deg": True,
                                    "insertion_mm": 2}), "orientation_deg must be a finite number"),
    "bad_kind": (json.dumps({"trial": "t", "tool": "k", "kind": "twist", "orientation_deg": 1,
                             "insertion_mm": 2}), "kind 'twist' must be normal or shear"),
    "empty_tool": (json.dumps({"trial": "t", "tool": "", "kind": "normal", "orientation_deg": 1,
                               "insertion_mm": 2}), "tool must be a non-empty string"),
    "infinite_number": ('{"trial": "t", "tool": "k", "kind": "normal", "orientation_deg": 1e999, "insertion_mm": 2}',
                        "orientation_deg must be a finite number"),
    "orientation_out_of_range": (json.dumps({"trial": "t", "tool": "k", "kind": "normal", "orientation_deg": 5000,
                                             "insertion_mm": 2}), r"orientation_deg 5000 is outside -360 to 360"),
    "negative_insertion": (json.dumps({"trial": "t", "tool": "k", "kind": "normal", "orientation_deg": 5,
                                        "insertion_mm": -0.014}), r"insertion_mm -0.014 is outside 0 to 200"),
    "tool_with_a_space": (json.dumps({"trial": "t", "tool": "Screwdriver 1", "kind": "normal", "orientation_deg": 1,
                                      "insertion_mm": 2}), r"tool name 'Screwdriver 1' must be lowercase .*'screwdriver_1'"),
}
for _name, (_text, _problem) in META_CASES.items():
    @case(f"native_meta_json/{_name}")
    def _(c, text=_text, problem=_problem):
        trial = _native(c)
        path = trial / "meta.json"
        if text is None:
            path.unlink()
        else:
            path.write_bytes(text if isinstance(text, bytes) else text.encode())
        return Case(c.native(trial), path, problem)


def _cal(rows: dict[str, str]) -> str:
    body = "".join(f'<UserAxis Name="{k}" values="{v}"/>' for k, v in rows.items())
    return f'<FTSensor><Calibration ForceUnits="N" TorqueUnits="N-mm">{body}</Calibration></FTSensor>'


_ROW = "1 0 0 0 0 0"
_GOOD = {"Fx": "10 0.2 0 0 0 0", "Fy": "0 10 0 0 0 0", "Fz": "0 0 14 0 0 0", "Tx": "0 0 0 100 0 0",
         "Ty": "0 0 0 0 100 0", "Tz": "0 0 0 0 0 100"}
CAL_CASES = {
    "missing": (None, "missing: the session needs the Nano17 calibration file", None),
    "not_xml": ("this is not xml", "not valid calibration XML", None),
    "binary_garbage": (np.random.default_rng(2).bytes(300), "not valid calibration XML", None),
    "row_missing": (_cal({a: _ROW for a in ("Fx", "Fy", "Fz", "Tx", "Ty")}), r"UserAxis rows missing: \['Tz'\]", None),
    "non_numeric": (_cal({a: (_ROW if a != "Fz" else "1 0 x 0 0 0") for a in ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")}),
                    "non-numeric calibration value", "UserAxis Fz"),
    "five_values": (_cal({a: (_ROW if a != "Ty" else "1 0 0 0 0") for a in ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")}),
                    "calibration rows need 6 values, got 5", "UserAxis Ty"),
    "nan_value": (_cal({a: (_ROW if a != "Fx" else "nan 0 0 0 0 0") for a in ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")}),
                  "must be finite", "UserAxis Fx"),
    "row_twice": (_cal({a: _ROW for a in ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")}).replace(
        "</Calibration>", f'<UserAxis Name="Fz" values="{_ROW}"/></Calibration>'), "given more than once", None),
    "unknown_force_unit": (_cal(_GOOD).replace('ForceUnits="N"', 'ForceUnits="furlongs"'),
                           "ForceUnits='furlongs' on <Calibration>: the unit must be one of N, kN, lbf", None),
    "no_units": (_cal(_GOOD).replace(' ForceUnits="N" TorqueUnits="N-mm"', ""), "no ForceUnits on <Calibration>", None),
    "six_equal_rows": (_cal({a: "10 0.2 0 0 0 0" for a in _GOOD}), "singular or nearly", None),
    "one_huge_cell": (_cal({**_GOOD, "Fz": "0 0 1e300 0 0 0"}), r"value 3 of the row, 1e\+300, is out of range",
                      "UserAxis Fz"),
    "namespaced_xml": (_cal(_GOOD).replace("<FTSensor>", '<FTSensor xmlns="urn:x">'),
                       "the XML declares the namespace 'urn:x'", None),
    "huge_row": (_cal({**_GOOD, "Fy": "0 2000 0 0 0 0"}), r"value 2 of the row, 2000, is out of range: alone it maps "
                                                          r"the ADC's 5 V to 1e\+04 N, beyond 2.5e\+03 N", "UserAxis Fy"),
    "huge_row_of_small_cells": (_cal({**_GOOD, "Fy": "0 400 400 400 0 0"}),
                                r"the row maps the ADC's 5 V to 6e\+03 N, outside 6.25-2.5e\+03 N", "UserAxis Fy"),
}
for _name, (_text, _problem, _record) in CAL_CASES.items():
    @case(f"native_calibration/{_name}")
    def _(c, text=_text, problem=_problem, record=_record):
        trial = _native(c)
        path = trial.parent / "nano17.cal"
        if text is None:
            path.unlink()
        else:
            path.write_bytes(text if isinstance(text, bytes) else text.encode())
        return Case(c.native(trial), path, problem, record)


SERIAL_ERROR_CASES = {
    "missing": (None, "missing: every trial needs the Arduino's force.log", None),
    "empty": (b"", "serial log is empty", None),
    "no_header": ("\n".join(serial_lines()).encode(), "first line must be", "line 1"),
    "header_out_of_range": (f"# start_host_ns={10**30}\n".encode() + "\n".join(serial_lines()).encode(),
                            "out of range", "line 1"),
    "clock_reset": (None, r"Arduino clock jumps back from 2206 to 3 ms \(a reset mid-trial\?\)", "line 21"),
    "duplicated_timestamp": (None, "duplicated Arduino timestamp 1603 ms", "line 12"),
    "mostly_garbage": (None, r"lines are unreadable .*garbage bytes", None),
    "all_wrong_columns": (None, r"no valid samples in 40 lines \(\{'wrong column count': 40\}\)", None),
    "binary_noise": (np.random.default_rng(4).bytes(5000), "first line must be|serial log is empty", None),
}


def _serial_text(name: str) -> bytes | None:
    lines = serial_lines()
    if name == "clock_reset":
        lines[19] = "3,512,512,512,512,512,512"          # the Arduino rebooted: millis() restarts
    elif name == "duplicated_timestamp":
        lines[10] = lines[9]
    elif name == "mostly_garbage":
        lines = [ln if i % 3 else "\x00\x13\x7f" + ln[3:] for i, ln in enumerate(lines)]
    elif name == "all_wrong_columns":
        lines = [ln.rsplit(",", 1)[0] for ln in lines]
    else:
        return None
    return ("\n".join([f"# start_host_ns={START_NS}", *lines]) + "\n").encode("latin-1")


for _name, (_text, _problem, _record) in SERIAL_ERROR_CASES.items():
    @case(f"native_serial_log/{_name}")
    def _(c, name=_name, text=_text, problem=_problem, record=_record):
        trial = _native(c)
        path = trial / "force.log"
        data = _serial_text(name) if text is None else text
        if data is None and name == "missing":
            path.unlink()
        else:
            path.write_bytes(data)
        return Case(c.native(trial), path, problem, record)


# The native trial's force clock, refined against the images (tool/data/clock_sync.py)

def _rewrite_frames(trial: Path, sensor: str, frame) -> None:
    for i in range(N_FRAMES):
        cv2.imwrite(str(_png(trial, sensor, i)), frame(i))


@case("native_clock/frozen_camera")
def _(c):
    trial = _native(c)
    _rewrite_frames(trial, "digit_right", lambda i: digit_frame(0))
    return Case(c.native(trial), _png(trial, "digit_right", 0),
                rf"digit_right: frames 0-{N_FRAMES - 1} of {N_FRAMES} are bit-identical .* the camera froze")


@case("native_clock/flat_force_log")
def _(c):
    trial = _native(c)
    write_serial(trial / "force.log", [ln.rsplit(",", 4)[0] + ",512,512,512,512" for ln in serial_lines()])
    return Case(c.native(trial), trial, "the force log is flat")


@case("native_clock/images_do_not_follow_the_force")
def _(c):
    trial = _native(c)
    for seed, s in enumerate(("digit_left", "digit_right")):      # each camera shuffled its own way
        order = np.random.default_rng(seed).permutation(N_FRAMES)
        _rewrite_frames(trial, s, lambda i, order=order: digit_frame(int(order[i])))
    return Case(c.native(trial), trial, "cannot align the force clock|on the edge of the search window")


# The public dataset layout of study 000 -> public_layout + ingest

def _pub(c: Ctx, trial: str = "t0", kind: str = "data_normal") -> Path:
    return c.copy("public") / kind / trial


PUBLIC_CASES = {
    "missing_tactile2_folder": (lambda t: shutil.rmtree(t / "tactile2"), lambda t: t / "tactile2",
                                "missing: every public trial needs a tactile2/ folder"),
    "force_file_missing": (lambda t: (t / "force" / "force_data_0003.txt").unlink(),
                           lambda t: t / "tactile1" / "tactile_frame_0003.jpg", "no force file force/force_data_0003.txt"),
    "frame_missing": (lambda t: (t / "tactile2" / "tactile_frame_0002.jpg").unlink(),
                      lambda t: t / "force" / "force_data_0002.txt", "no tactile2/tactile_frame_0002.jpg"),
    "index_used_twice": (lambda t: shutil.copy(t / "force" / "force_data_0001.txt", t / "force" / "force_data_1.txt"),
                         lambda t: t / "force", r"index 1 also used by"),
    "force_file_empty": (lambda t: (t / "force" / "force_data_0004.txt").write_text(""),
                         lambda t: t / "force" / "force_data_0004.txt", "empty force file"),
    "force_non_numeric": (lambda t: (t / "force" / "force_data_0004.txt").write_text("4,abc\n"),
                          lambda t: t / "force" / "force_data_0004.txt", "is not a number"),
    "force_nan": (lambda t: (t / "force" / "force_data_0002.txt").write_text("2,nan\n"),
                  lambda t: t / "force" / "force_data_0002.txt", "non-finite force value"),
    "force_not_utf8": (lambda t: (t / "force" / "force_data_0002.txt").write_bytes(b"\xff\xfe\x00"),
                       lambda t: t / "force" / "force_data_0002.txt", "unreadable force file"),
    "frame_unreadable": (lambda t: (t / "tactile1" / "tactile_frame_0002.jpg").write_bytes(b"\xff\xd8\xff garbage"),
                         lambda t: t / "tactile1" / "tactile_frame_0002.jpg", "unreadable or missing image"),
    # a camera-noisy frame cut in half: OpenCV's imread decodes the rows present, the rest grey
    "frame_truncated_jpeg": (lambda t: (cv2.imwrite(str(t / "tactile2" / "tactile_frame_0003.jpg"), noisy(digit_frame(3, 48, 64))),
                                        truncate(t / "tactile2" / "tactile_frame_0003.jpg", 0.5)),
                             lambda t: t / "tactile2" / "tactile_frame_0003.jpg", "truncated JPEG"),
    "frame_truncated_png": (lambda t: (cv2.imwrite(str(t / "tactile1" / "tactile_frame_0004.png"), digit_frame(4, 48, 64)),
                                       (t / "tactile1" / "tactile_frame_0004.jpg").unlink(),
                                       truncate(t / "tactile1" / "tactile_frame_0004.png", 0.5)),
                            lambda t: t / "tactile1" / "tactile_frame_0004.png", "truncated PNG"),
    "jpg_and_png_of_one_index": (lambda t: cv2.imwrite(str(t / "tactile1" / "tactile_frame_0001.png"),
                                                       digit_frame(1, 48, 64)),
                                 lambda t: t / "tactile1", "index 1 also used by"),
    "frame_size_differs": (lambda t: cv2.imwrite(str(t / "tactile2" / "tactile_frame_0004.jpg"), digit_frame(4, 40, 64)),
                           lambda t: t / "tactile2" / "tactile_frame_0004.jpg", "differs from the trial's first frame"),
    "all_black_frame": (lambda t: cv2.imwrite(str(t / "tactile1" / "tactile_frame_0003.jpg"),
                                              np.zeros((48, 64, 3), np.uint8)),
                        lambda t: t / "tactile1", "frame is all black"),
    "saturated_frame": (lambda t: cv2.imwrite(str(t / "tactile2" / "tactile_frame_0001.jpg"),
                                              np.full((48, 64, 3), 255, np.uint8)),
                        lambda t: t / "tactile2", "frame is saturated"),
    "empty_trial": (lambda t: [p.unlink() for d in ("tactile1", "tactile2", "force") for p in (t / d).iterdir()],
                    lambda t: t / "force", "empty trial"),
    "every_label_below_zero": (lambda t: [(t / "force" / f"force_data_{i:04d}.txt").write_text(f"{i},2000\n")
                                          for i in range(6)],
                               lambda t: t, r"no frames of .* to ingest \(public: below 0 N 6 dropped\)"),
}
for _name, (_break, _where, _problem) in PUBLIC_CASES.items():
    @case(f"public_layout/{_name}")
    def _(c, brk=_break, where=_where, problem=_problem):
        trial = _pub(c)
        brk(trial)
        return Case(c.public(trial), where(trial), problem)


@case("public_layout/shear_wrong_field_count")
def _(c):
    trial = _pub(c, "s0", "data_shear")
    path = trial / "force" / "force_data_0003.txt"
    path.write_text("1.0,2.0\n")
    return Case(c.public(trial), path, "expected 'fx,fy,fz'", "line 1")


@case("public_layout/trials_csv_bad_number")
def _(c):
    trial = _pub(c)
    path = trial.parent.parent / "trials.csv"
    path.write_text("trial,tool,orientation_deg,insertion_mm\nt0,knife,ten,3\n")
    return Case(c.public(trial), path, "expected trial,tool,orientation_deg,insertion_mm", "line 2")


TRIALS_CSV_CASES = {
    "missing": (None, "missing: a public-layout session needs trials.csv", None),
    "trial_without_a_row": ("trial,tool,orientation_deg,insertion_mm\ns0,knife,5,10\n",
                            r"no tool for 1 of 1 public trials: data_normal/t0", None),
    # a template row (tactilepipe study000-unpack writes them) not filled in: the trial lacks a tool
    "empty_tool": ("trial,tool,orientation_deg,insertion_mm\nt0,,5,10\n",
                   r"no tool for 1 of 1 public trials: data_normal/t0; complete their rows", None),
    "empty_pose": ("trial,tool,orientation_deg,insertion_mm\nt0,knife,,\n",
                   r"no tool for 1 of 1 public trials: data_normal/t0", None),
    "empty_trial": ("trial,tool,orientation_deg,insertion_mm\n,knife,5,10\n", "trial must not be empty", "line 2"),
    "trial_listed_twice": ("trial,tool,orientation_deg,insertion_mm\nt0,knife,5,10\nt0,spatula,5,10\n",
                           "trial t0 is listed again", "line 3"),
    "wrong_header": ("name,tool\nt0,knife\n", "header must hold trial,tool,orientation_deg,insertion_mm", "line 1"),
    "tool_with_a_space": ("trial,tool,orientation_deg,insertion_mm\nt0,paper knife,5,10\n",
                          r"tool name 'paper knife' must be lowercase letters, digits and _ .*'paper_knife'", "line 2"),
}
for _name, (_text, _problem, _record) in TRIALS_CSV_CASES.items():
    @case(f"public_trials_csv/{_name}")
    def _(c, text=_text, problem=_problem, record=_record):
        trial = _pub(c)
        path = trial.parent.parent / "trials.csv"
        if text is None:
            path.unlink()
        else:
            path.write_text(text)
        return Case(c.public(trial), path, problem, record)


@case("public_trials_csv/session_listing_names_every_trial_lacking_a_tool")
def _(c):
    from tactilepipe.tool.formats.trials import list_trials
    session = c.copy("public")
    path = session / "trials.csv"
    path.write_text("trial,tool,orientation_deg,insertion_mm\nother,knife,5,10\n")
    return Case(lambda: list_trials(session), path, r"no tool for 2 of 2 public trials: data_normal/t0, data_shear/s0")


def test_public_trial_takes_its_tool_from_trials_csv_with_bom_and_kind_prefix(tmp_path, goods):
    c = Ctx(tmp_path, goods)
    trial = _pub(c)
    (trial.parent.parent / "trials.csv").write_bytes(
        "\ufefftrial,tool,orientation_deg,insertion_mm\r\ndata_normal/t0,spatula,7,12\r\ns0,knife,5,10\r\n".encode())
    raw = open_trial(trial, "public")
    assert (raw.tool, raw.orientation_deg, raw.insertion_mm) == ("spatula", 7.0, 12.0)


# Intermediate files a later stage reads: shards

SHARD_READERS = {
    "volume_dataset": lambda p, c: read_shard(p),
    "drift_analysis": lambda p, c: recording_reading(p, "loaded", 4.9),
    "tool_dataset": lambda p, c: build_tool_dataset([p], "normal", c.out / "data", SYNC),
}
SHARD_BREAKS = {
    "truncated": (lambda p: truncate(p, 0.5), "cannot read shard"),
    "empty": (lambda p: p.write_bytes(b""), "cannot read shard"),
    "not_parquet": (lambda p: p.write_text("a,b\n1,2\n"), "cannot read shard"),
}
for _reader, _fn in SHARD_READERS.items():
    for _name, (_break, _problem) in SHARD_BREAKS.items():
        @case(f"shard_for_{_reader}/{_name}")
        def _(c, fn=_fn, brk=_break, problem=_problem):
            shard = c.copy("shard")
            brk(shard)
            return Case(lambda: fn(shard, c), shard, problem)


@case("shard_for_tool_dataset/volume_shard_given")
def _(c):
    shard = c.copy("shard")
    return Case(lambda: build_tool_dataset([shard], "normal", c.out / "data", SYNC), shard,
                "not a tool shard")


@case("shard_for_drift_analysis/missing_columns")
def _(c):
    import pandas as pd
    shard = c.tmp / "in" / "loaded_t05.parquet"
    shard.parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame({"x": [1.0]}).to_parquet(shard)
    return Case(lambda: recording_reading(shard, "loaded", 4.9), shard, "needs columns stamp_ns, sensor, gfz")


# Session labels of the volume scene: lifts.csv

LIFTS_CASES = {
    "missing": (None, "missing: every recording session needs lifts.csv", None),
    "wrong_header": ("bag,volume\na.bag,50\n", "header must hold bag,volume_ml,set", None),
    "non_numeric_volume": ("bag,volume_ml,set\na.bag,fifty,main\n", "volume_ml 'fifty' is not a number", "line 2"),
    "negative_volume": ("bag,volume_ml,set\na.bag,-5,main\n", "must be finite and >= 0", "line 2"),
    "bad_set": ("bag,volume_ml,set\na.bag,50,test\n", "set 'test' must be main or unseen", "line 2"),
    "header_only": ("bag,volume_ml,set\n", "no lifts: the file holds only its header", None),
    "bag_listed_twice": ("bag,volume_ml,set\na.bag,100,main\nb.bag,50,main\na.bag,100,main\n",
                         r"bag a.bag is listed again \(first on line 2\)", "line 4"),
    "bag_with_conflicting_volumes": ("bag,volume_ml,set\na.bag,100,main\n./a.bag,150,main\n",
                                     r"bag a.bag is listed again \(first on line 2, with 100.0 ml, main\)", "line 3"),
    "bag_in_a_sub_folder": ("bag,volume_ml,set\nx.bag,100,main\n./sub/x.bag,150,main\n",
                            "must be a file name in the session folder", "line 3"),
    "bag_outside_the_session": ("bag,volume_ml,set\n../x.bag,100,main\n", "must be a file name in the session folder",
                                "line 2"),
    "not_a_bag": ("bag,volume_ml,set\nx.mcap,100,main\n", "must be a ROS1 .bag file", "line 2"),
    "row_too_short": ("bag,volume_ml,set\nx.bag,100\n", "too few fields", "line 2"),
}
for _name, (_text, _problem, _record) in LIFTS_CASES.items():
    @case(f"volume_lifts_csv/{_name}")
    def _(c, text=_text, problem=_problem, record=_record):
        session = c.tmp / "in" / "s1"
        session.mkdir(parents=True)
        if text is not None:
            (session / "lifts.csv").write_text(text)
        return Case(lambda: read_session_labels(session), session / "lifts.csv", problem, record)


def test_lifts_csv_with_a_byte_order_mark_and_spaces_reads(tmp_path):
    session = tmp_path / "lab session 1"
    session.mkdir()
    (session / "lifts.csv").write_bytes("\ufeffbag,volume_ml,set\r\nlift 1.bag,100,main\r\n./b.bag,50,unseen\r\n"
                                        .encode("utf-8"))
    assert read_session_labels(session) == [{"bag": "lift 1.bag", "volume_ml": 100.0, "set": "main"},
                                            {"bag": "b.bag", "volume_ml": 50.0, "set": "unseen"}]


# params.yaml

def _params_case(c: Ctx, change: Callable[[dict], None] | str, problem: str) -> Case:
    raw = yaml.safe_load((REPO / "params.yaml").read_text())
    path = c.tmp / "in" / "params.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(change, str):
        path.write_text(change)
    else:
        change(raw)
        path.write_text(yaml.safe_dump(raw))
    return Case(lambda: load_params(path), path, problem, error=ConfigError)


PARAMS_CASES = {
    "wrong_type_top_level": (lambda r: r.__setitem__("seed", "forty-two"), r"invalid parameter at 'seed'"),
    "wrong_type_nested": (lambda r: r["folds"].__setitem__("n_folds", "five"), r"'folds.n_folds'"),
    "list_instead_of_mapping": (lambda r: r.__setitem__("mlp", [1, 2]), r"'mlp'"),
    "unknown_top_level_key": (lambda r: r.__setitem__("mlpp", 1), r"'mlpp' was unexpected"),
    "unknown_nested_key": (lambda r: r["folds"].__setitem__("n_fold", 3), r"'n_fold' was unexpected"),
    "missing_group": (lambda r: r.pop("folds"), r"'folds' is a required property"),
    "unknown_scale": (lambda r: r.__setitem__("scale", "huge"), r"unknown scale 'huge'"),
    "bool_for_number": (lambda r: r["folds"].__setitem__("n_folds", True), r"'folds.n_folds'"),
    "yaml_syntax_error": ("seed: [1, 2\n", r"not valid YAML at line"),
    "not_a_mapping": ("- 1\n- 2\n", r"expected a mapping"),
    "empty_file": ("", r"expected a mapping"),
    "binary_garbage": ("\x00\x01\x02", r"not valid YAML|expected a mapping"),
}
for _name, (_change, _problem) in PARAMS_CASES.items():
    @case(f"params_yaml/{_name}")
    def _(c, change=_change, problem=_problem):
        return _params_case(c, change, problem)


# --- the rule, applied to every case ---------------------------------------------------------------

@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")
@pytest.mark.parametrize("name", list(CASES))
def test_bad_input_gives_a_clear_error_and_writes_nothing(name, tmp_path, goods):
    c = Ctx(tmp_path, goods)
    expect = CASES[name](c)
    with pytest.raises(Exception) as info:
        expect.run()
    err = info.value
    assert type(err) is expect.error, f"{type(err).__name__}: {err}"         # never a library's exception
    msg = str(err)
    assert "\n" not in msg and len(msg) < 600, msg                           # one line
    assert msg.startswith(str(expect.path)), f"should name {expect.path}: {msg}"
    assert re.search(expect.problem, msg), msg
    if expect.record is not None:      # the record: InputError.record, or in brackets after the file
        assert re.search(expect.record, str(err.record)) or re.search(r"\[" + expect.record, msg), msg
    assert list(c.out.rglob("*")) == [] or all(p.is_dir() for p in c.out.rglob("*")), list(c.out.rglob("*"))
    assert not [p for p in tmp_path.rglob("*") if p.name.endswith(".tmp")]


# --- counted drops: kept going, and the count reaches the shard's QC record -----------------------

def test_garbled_serial_lines_are_dropped_and_counted_in_the_shard(tmp_path, goods):
    c = Ctx(tmp_path, goods)
    trial = _native(c)
    lines = serial_lines(60)
    lines.insert(0, "5,512,51")                          # the port opened mid-line
    lines.insert(10, "\xff\xfe garbage")                  # non-ASCII bytes
    lines.insert(15, "1603,512,\x00512,512,512,512,512")  # a control byte inside a line
    lines.insert(20, "1800,512,512,abc,512,512,512")      # a non-numeric value
    lines.insert(25, "2100,512,512,512,512,512")          # a column missing
    lines.insert(30, "2400,512,512,512,512,512,5120")     # out of the 10-bit range
    lines.insert(35, "2700,512,512,5_12,512,512,512")     # int() would read this as 512
    lines.insert(40, "99999999999,512,512,512,512,512,512")   # beyond millis()' 32 bits
    lines.append("5999,51")                               # cut off when logging stopped
    write_serial(trial / "force.log", lines, end=b"")
    info = ingest_trial(open_trial(trial, "native"), c.out / "s.parquet", SIZE, INGEST)
    drops = read_shard_info(c.out / "s.parquet")["drops"]
    assert drops == info["drops"] == {
        "serial: wrong column count": 2, "serial: garbage bytes": 2, "serial: non-numeric field": 2,
        "serial: ADC count out of range": 1, "serial: time out of range": 1, "serial: truncated last line": 1}
    assert info["force_samples"] == 60


def test_public_frames_below_zero_newton_are_dropped_and_counted(tmp_path, goods):
    c = Ctx(tmp_path, goods)
    trial = _pub(c)
    for i in (1, 4):
        (trial / "force" / f"force_data_{i:04d}.txt").write_text(f"{i},1000\n")      # -0.97 N
    info = ingest_trial(open_trial(trial, "public"), c.out / "s.parquet", SIZE, INGEST)
    assert info["drops"] == {"public: below 0 N": 2}
    assert info["frames"] == {"digit_left": 4, "digit_right": 4}
    assert read_shard_info(c.out / "s.parquet")["drops"] == {"public: below 0 N": 2}


def test_every_kind_of_bad_input_in_the_issue_is_in_the_corpus():
    """The issue's list, each kind matched by at least one case (ids are <reader>/<case>)."""
    ids = list(CASES)
    want = {
        "truncated ROS1 bag": r"^ros1_.*/truncated", "truncated ROS2 bag": r"^ros2_.*/truncated",
        "empty bag": r"/empty", "corrupt bag": r"overwritten|random_bytes|garbage", "wrong message type":
        r"wrong_message_type", "out-of-order timestamps": r"out_of_order", "duplicated timestamps": r"duplicated",
        "serial garbage bytes": r"serial_log/(mostly_garbage|binary)", "serial wrong column count":
        r"serial_log/all_wrong_columns", "serial clock reset": r"serial_log/clock_reset",
        "unreadable image": r"image/unreadable", "image of the wrong size": r"image/wrong_size",
        "wrong channel count": r"image/(grayscale|four_channels)", "all black image": r"all_black",
        "saturated image": r"saturated", "public layout missing files": r"public_layout/.*missing",
        "public layout mismatched files": r"public_layout/(index_used_twice|frame_size_differs)",
        "params wrong types": r"params_yaml/wrong_type", "params unknown keys": r"params_yaml/unknown",
        "frozen camera": r"native_clock/frozen_camera", "flat force log": r"native_clock/flat_force_log",
        "clock not found": r"native_clock/images_do_not_follow", "truncated JPEG": r"public_layout/frame_truncated_jpeg",
        "duplicate lifts.csv rows": r"volume_lifts_csv/bag_listed_twice|bag_with_conflicting",
        "header-only lifts.csv": r"volume_lifts_csv/header_only", "sub-folder bag": r"volume_lifts_csv/bag_in_a_sub",
        "missing or incomplete trials.csv": r"public_trials_csv/(missing|trial_without_a_row)",
        "other message definition": r"other_message_definition",
    }
    for kind, pattern in want.items():
        assert any(re.search(pattern, i) for i in ids), kind
