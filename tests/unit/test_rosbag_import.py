"""ROS bag importer of tool-force trials: round trips in ROS1 / ROS2 sqlite3 / ROS2 mcap, image
encodings, lazy decoding, sidecar metadata, and every damaged or unexpected input as InputError.

Bad recordings are written with rosbags directly (``_bag`` below), not with the module's writer,
so they do not depend on the code under test.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from support import ros_writer
from tactilepipe.core.errors import ArgumentError, InputError
from tactilepipe.tool.formats import rosbag as ri
from tactilepipe.tool.formats.raw import RawTrial

FORMATS = ros_writer.FORMATS
T0 = 1_767_225_600_000_000_000
META = {"tool": "screwdriver_small", "kind": "normal", "orientation_deg": 15.0, "insertion_mm": 12.5}
LEFT, RIGHT, WRENCH = ri.DEFAULT_TOPICS["digit_left"], ri.DEFAULT_TOPICS["digit_right"], ri.DEFAULT_TOPICS["wrench"]
STORES = {False: get_typestore(Stores.ROS1_NOETIC), True: get_typestore(Stores.ROS2_HUMBLE)}


# ------------------------------------------------------------------------------------------------
# synthetic data

def _frames(n: int, seed: int, h: int = 320, w: int = 240) -> np.ndarray:
    """DIGIT-like BGR frames: colour gradients with a moving blob and a little noise."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    out = np.empty((n, h, w, 3), np.uint8)
    for i in range(n):
        blob = 60 * np.exp(-((xx - w * (0.3 + 0.04 * i)) ** 2 + (yy - h / 2) ** 2) / 400.0)
        img = np.stack([60 + 120 * xx / w + blob, 70 + 110 * yy / h, 200 - 100 * xx / w - blob], axis=-1)
        img += rng.normal(0, 3, img.shape)
        out[i] = np.clip(img, 0, 255).astype(np.uint8)
    return out


@pytest.fixture(scope="module")
def trial_data():
    rng = np.random.default_rng(7)
    return {
        "left": _frames(10, 1), "right": _frames(8, 2),
        # separate cameras: different counts and times
        "stamps": {"digit_left": T0 + 33_333_333 * np.arange(10, dtype=np.int64),
                   "digit_right": T0 + 5_000_017 + 40_000_000 * np.arange(8, dtype=np.int64)},
        "force_ns": T0 + 1 + 66_666_667 * np.arange(5, dtype=np.int64),
        "force_n": rng.normal(0, 5, (5, 3)),
    }


def _write(path, data, fmt, compressed, **kw) -> Path:
    return ros_writer.write_ros_trial(path, data["left"], data["right"], data["stamps"], data["force_ns"],
                              data["force_n"], fmt, compressed, **kw)


def _bagpath(tmp_path: Path, fmt: str, name: str = "trial") -> Path:
    return tmp_path / (f"{name}.bag" if fmt == "ros1" else name)


# ------------------------------------------------------------------------------------------------
# an independent writer of hand-made (possibly bad) bags

def _header(ros2, stamp_ns, seq=0, frame_id="f"):
    t = STORES[ros2].types
    stamp = t["builtin_interfaces/msg/Time"](sec=int(stamp_ns) // 10**9, nanosec=int(stamp_ns) % 10**9)
    if ros2:
        return t["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)
    return t["std_msgs/msg/Header"](seq=seq, stamp=stamp, frame_id=frame_id)


def _image(ros2, stamp, pixels, encoding="bgr8", step=None, data=None, seq=0):
    pixels = np.asarray(pixels, np.uint8)
    h, w = pixels.shape[:2]
    ch = 1 if pixels.ndim == 2 else pixels.shape[2]
    step = w * ch if step is None else step
    if data is None:
        rows = np.full((h, step), 0xAB, np.uint8)        # padding bytes a reader must skip
        rows[:, :w * ch] = pixels.reshape(h, w * ch)
        data = rows.reshape(-1)
    return STORES[ros2].types[ri.IMAGE](header=_header(ros2, stamp, seq), height=h, width=w, encoding=encoding,
                                        is_bigendian=0, step=step, data=np.asarray(data, np.uint8))


def _compressed(ros2, stamp, data: bytes, fmt="png", seq=0):
    return STORES[ros2].types[ri.COMPRESSED_IMAGE](header=_header(ros2, stamp, seq), format=fmt,
                                                   data=np.frombuffer(data, np.uint8))


def _wrench(ros2, stamp, f=(1.0, 2.0, 3.0), seq=0):
    t = STORES[ros2].types
    v = t["geometry_msgs/msg/Vector3"]
    return t[ri.WRENCH_STAMPED](header=_header(ros2, stamp, seq),
                                wrench=t["geometry_msgs/msg/Wrench"](force=v(x=f[0], y=f[1], z=f[2]),
                                                                     torque=v(x=0.0, y=0.0, z=0.0)))


def _string(ros2, text="hi"):
    return STORES[ros2].types["std_msgs/msg/String"](data=text)


def _bag(path: Path, fmt: str, topics: dict) -> Path:
    """``{topic: (msgtype, [(receive_ns, msg), ...])}`` written with rosbags as they come."""
    ros2 = fmt != "ros1"
    store = STORES[ros2]
    if ros2:
        from rosbags.rosbag2 import StoragePlugin, Writer
        plugin = StoragePlugin.SQLITE3 if fmt == "ros2_sqlite3" else StoragePlugin.MCAP
        writer = Writer(path, version=9, storage_plugin=plugin)
        ser = store.serialize_cdr
    else:
        from rosbags.rosbag1 import Writer
        writer = Writer(path)
        ser = store.serialize_ros1
    with writer:
        for topic, (msgtype, msgs) in topics.items():
            conn = writer.add_connection(topic, msgtype, typestore=store)
            for t, msg in msgs:
                writer.write(conn, int(t), ser(msg, msgtype))
    return path


def _good_topics(ros2: bool, n: int = 3, size=(6, 8)) -> dict:
    """A valid small recording: two bgr8 image topics and a wrench topic."""
    px = _frames(n, 3, *size)
    return {
        LEFT: (ri.IMAGE, [(T0 + i * 10, _image(ros2, T0 + i * 10, px[i], seq=i)) for i in range(n)]),
        RIGHT: (ri.IMAGE, [(T0 + i * 10 + 3, _image(ros2, T0 + i * 10 + 3, px[i], seq=i)) for i in range(n)]),
        WRENCH: (ri.WRENCH_STAMPED, [(T0 + i * 7, _wrench(ros2, T0 + i * 7, seq=i)) for i in range(n)]),
    }


def _raises(path, match, fn=None, meta=META, topics=ri.DEFAULT_TOPICS) -> InputError:
    """read_ros_trial (or fn) raises an InputError naming the bag, with no library traceback chained."""
    with pytest.raises(InputError, match=match) as info:
        (fn or (lambda: ri.read_ros_trial(path, meta, topics)))()
    assert info.value.path == str(path)
    assert str(path) in str(info.value)
    assert info.value.__cause__ is None
    assert info.value.__context__ is None or info.value.__suppress_context__
    return info.value


# ------------------------------------------------------------------------------------------------
# round trips

@pytest.mark.parametrize("compressed", [False, True], ids=["image_bgr8", "compressed_png"])
@pytest.mark.parametrize("fmt", FORMATS)
def test_round_trip(tmp_path, trial_data, fmt, compressed):
    bag = _write(_bagpath(tmp_path, fmt), trial_data, fmt, compressed)
    if fmt == "ros1":
        assert bag.is_file() and bag.read_bytes()[:12] == b"#ROSBAG V2.0"
    else:
        assert (bag / "metadata.yaml").is_file()
        ext = ".db3" if fmt == "ros2_sqlite3" else ".mcap"
        assert (bag / f"{bag.name}{ext}").is_file()
    assert [p.name for p in tmp_path.iterdir()] == [bag.name]       # no temporary leftovers

    trial = ri.read_ros_trial(bag, META)
    assert isinstance(trial, RawTrial)
    assert (trial.trial, trial.tool, trial.kind) == ("trial", "screwdriver_small", "normal")
    assert (trial.orientation_deg, trial.insertion_mm) == (15.0, 12.5)
    assert trial.clock == {"method": "ros_header_stamps", "offset_s": 0.0}
    assert trial.source == str(bag) and trial.drops == {}
    assert set(trial.frames) == {"digit_left", "digit_right"}
    for key, frames in (("digit_left", trial_data["left"]), ("digit_right", trial_data["right"])):
        sf = trial.frames[key]
        assert len(sf) == len(frames) == len(sf.source)
        assert sf.host_ns.dtype == np.int64
        np.testing.assert_array_equal(sf.host_ns, trial_data["stamps"][key])
        assert ri.DEFAULT_TOPICS[key] in sf.source[0] and "message 0" in sf.source[0]
        for i in range(len(frames)):
            img = sf.load(i)
            assert img.dtype == np.uint8 and img.shape == (320, 240, 3)
            np.testing.assert_array_equal(img, frames[i])
    np.testing.assert_array_equal(trial.force_host_ns, trial_data["force_ns"])
    assert trial.force_n.shape == (5, 3)
    np.testing.assert_array_equal(trial.force_n, trial_data["force_n"])   # float64 in the message: exact


@pytest.mark.parametrize("fmt", ["ros1", "ros2_mcap"])
@pytest.mark.parametrize("encoding", ["rgb8", "mono8"])
def test_rgb8_and_mono8_become_bgr(tmp_path, trial_data, fmt, encoding):
    bag = _write(_bagpath(tmp_path, fmt), trial_data, fmt, False, encoding=encoding)
    trial = ri.read_ros_trial(bag, META)
    for i in (0, 7):
        got = trial.frames["digit_right"].load(i)
        want = trial_data["right"][i]
        if encoding == "mono8":
            gray = cv2.cvtColor(want, cv2.COLOR_BGR2GRAY)
            want = np.repeat(gray[..., None], 3, axis=2)
        assert got.shape == (320, 240, 3) and got.flags.c_contiguous
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("fmt", FORMATS)
def test_compressed_jpeg(tmp_path, trial_data, fmt):
    bag = _write(_bagpath(tmp_path, fmt), trial_data, fmt, True, codec="jpeg", jpeg_quality=95)
    trial = ri.read_ros_trial(bag, META)
    for i in range(10):
        got = trial.frames["digit_left"].load(i).astype(int)
        diff = np.abs(got - trial_data["left"][i].astype(int))
        assert got.shape == (320, 240, 3)
        assert diff.mean() < 3.0 and np.percentile(diff, 99) < 15


def test_frames_are_decoded_lazily_and_out_of_order(tmp_path, trial_data, monkeypatch):
    bag = _write(tmp_path / "t.bag", trial_data, "ros1", True)
    calls = []
    real = cv2.imdecode
    monkeypatch.setattr(ri.cv2, "imdecode", lambda *a: calls.append(1) or real(*a))
    trial = ri.read_ros_trial(bag, META)
    assert calls == []                                   # reading the bag decodes no image
    sf = trial.frames["digit_left"]
    for i in (9, 2, 5, 0, 2):
        np.testing.assert_array_equal(sf.load(i), trial_data["left"][i])
    assert len(calls) == 5
    np.testing.assert_array_equal(sf.load(-1), trial_data["left"][9])
    with pytest.raises(IndexError):
        sf.load(10)
    a = sf.load(3)
    a[:] = 0                                             # a fresh array each time
    np.testing.assert_array_equal(sf.load(3), trial_data["left"][3])


def test_raw_image_frames_are_fresh_arrays(tmp_path, trial_data):
    trial = ri.read_ros_trial(_write(tmp_path / "t", trial_data, "ros2_sqlite3", False), META)
    a = trial.frames["digit_right"].load(4)
    assert a.flags.writeable and a.flags.owndata
    a[:] = 0
    np.testing.assert_array_equal(trial.frames["digit_right"].load(4), trial_data["right"][4])


@pytest.mark.parametrize("fmt", FORMATS)
def test_header_stamps_not_receive_times_and_step_padding(tmp_path, fmt):
    ros2 = fmt != "ros1"
    bgr = _frames(3, 5, 7, 9)                            # odd sizes
    gray = bgr[..., 1]
    stamps = [T0 + 100, T0 + 200, T0 + 300]
    recv = [T0 + 10_000_000 + k * 5 for k in range(3)]   # late and jittery receive times
    topics = {
        LEFT: (ri.IMAGE, [(recv[k], _image(ros2, stamps[k], bgr[k], step=9 * 3 + 5, seq=k)) for k in range(3)]),
        RIGHT: (ri.IMAGE, [(recv[k], _image(ros2, stamps[k] + 1, gray[k], "mono8", step=12, seq=k))
                           for k in range(3)]),
        WRENCH: (ri.WRENCH_STAMPED, [(recv[k], _wrench(ros2, stamps[k] + 2, (k, -k, 0.5 * k), seq=k))
                                     for k in range(3)]),
    }
    bag = _bag(_bagpath(tmp_path, fmt), fmt, topics)
    trial = ri.read_ros_trial(bag, META)
    np.testing.assert_array_equal(trial.frames["digit_left"].host_ns, stamps)
    np.testing.assert_array_equal(trial.frames["digit_right"].host_ns, np.array(stamps) + 1)
    np.testing.assert_array_equal(trial.force_host_ns, np.array(stamps) + 2)
    np.testing.assert_array_equal(trial.force_n, [[0, 0, 0], [1, -1, 0.5], [2, -2, 1.0]])
    for k in range(3):
        np.testing.assert_array_equal(trial.frames["digit_left"].load(k), bgr[k])
        np.testing.assert_array_equal(trial.frames["digit_right"].load(k), np.repeat(gray[k][..., None], 3, 2))


def test_single_sensor_and_custom_topics(tmp_path, trial_data):
    topics = {"digit_left": "/cam/left/image/compressed", "wrench": "/ft/wrench"}
    bag = ros_writer.write_ros_trial(tmp_path / "one", trial_data["left"], None, trial_data["stamps"]["digit_left"],
                             trial_data["force_ns"], trial_data["force_n"], "ros2_mcap", True, topics)
    trial = ri.read_ros_trial(bag, {**META, "trial": "s1/one"}, topics)
    assert list(trial.frames) == ["digit_left"] and trial.trial == "s1/one"
    np.testing.assert_array_equal(trial.frames["digit_left"].load(4), trial_data["left"][4])
    _raises(bag, r"image topic /digit_left/image_raw \(digit_left\) is not in the bag")


def test_shared_frame_stamps_and_bare_storage_file(tmp_path, trial_data):
    n = 8
    stamps = T0 + 33_000_000 * np.arange(n, dtype=np.int64)
    bag = ros_writer.write_ros_trial(tmp_path / "t", trial_data["left"][:n], trial_data["right"], stamps,
                             trial_data["force_ns"], trial_data["force_n"], "ros2_mcap", False)
    for path in (bag, bag / "t.mcap"):                   # the directory, or the storage file alone
        trial = ri.read_ros_trial(path, META)
        np.testing.assert_array_equal(trial.frames["digit_left"].host_ns, stamps)
        np.testing.assert_array_equal(trial.frames["digit_right"].host_ns, stamps)
        np.testing.assert_array_equal(trial.frames["digit_right"].load(7), trial_data["right"][7])


@pytest.mark.parametrize("fmt", FORMATS)
def test_write_replaces_an_existing_bag_atomically(tmp_path, trial_data, fmt):
    bag = _bagpath(tmp_path, fmt)
    _write(bag, trial_data, fmt, True)
    data2 = {**trial_data, "force_n": trial_data["force_n"] + 1.0}
    _write(bag, data2, fmt, True)
    assert [p.name for p in tmp_path.iterdir()] == [bag.name]
    np.testing.assert_array_equal(ri.read_ros_trial(bag, META).force_n, data2["force_n"])


def test_write_rejects_bad_arguments(tmp_path, trial_data):
    with pytest.raises(ValueError, match="fmt"):
        _write(tmp_path / "x", trial_data, "ros3", False)
    with pytest.raises(ArgumentError, match=r"digit_left: 10 frames but 5 stamps \(frames_left against frame_host_ns\)"):
        ros_writer.write_ros_trial(tmp_path / "x.bag", trial_data["left"], None, trial_data["force_ns"],
                           trial_data["force_ns"], trial_data["force_n"], "ros1", False)
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------------------------------
# sidecar metadata

def test_sidecar_meta(tmp_path, trial_data):
    bag = _write(tmp_path / "t07.bag", trial_data, "ros1", True)
    side = tmp_path / "t07.meta.json"
    assert ri.sidecar_path(bag) == side
    side.write_text(json.dumps({**META, "kind": "shear", "camera_fps": 60.0}))
    meta = ri.read_sidecar_meta(bag)
    assert meta["trial"] == "t07" and meta["kind"] == "shear" and meta["camera_fps"] == 60.0
    trial = ri.read_ros_trial(bag, meta)
    assert (trial.trial, trial.kind, trial.tool) == ("t07", "shear", "screwdriver_small")

    d = _write(tmp_path / "s1.t08", trial_data, "ros2_sqlite3", True)      # ROS2 dir: whole name
    assert ri.sidecar_path(d) == tmp_path / "s1.t08.meta.json"
    (tmp_path / "s1.t08.meta.json").write_text(json.dumps({**META, "trial": "s1/t08"}))
    assert ri.read_sidecar_meta(d)["trial"] == "s1/t08"


@pytest.mark.parametrize("content, match", [
    (None, "missing: a ROS bag trial needs a metadata sidecar"),
    ("{not json", "not valid JSON"),
    (json.dumps({"tool": "x", "kind": "normal", "orientation_deg": 0}), r"missing keys \['insertion_mm'\]"),
    (json.dumps({**META, "grip": 3}), r"unknown keys \['grip'\]"),
    (json.dumps({**META, "kind": "twist"}), "kind 'twist' must be normal or shear"),
    (json.dumps({**META, "insertion_mm": "deep"}), "insertion_mm must be a finite number"),
    (json.dumps([1, 2]), "must be a JSON object"),
])
def test_sidecar_meta_errors(tmp_path, content, match):
    bag = tmp_path / "t.bag"
    side = tmp_path / "t.meta.json"
    if content is not None:
        side.write_text(content)
    _raises(side, match, lambda: ri.read_sidecar_meta(bag))


def test_meta_argument_is_validated(tmp_path, trial_data):
    bag = _write(tmp_path / "t.bag", trial_data, "ros1", True)
    _raises(bag, r"missing keys \['tool'\]", meta={k: v for k, v in META.items() if k != "tool"})
    _raises(bag, "kind", meta={**META, "kind": "pull"})


# ------------------------------------------------------------------------------------------------
# damaged and unexpected recordings

@pytest.mark.parametrize("name", ["nope.bag", "nope_dir", "nope.mcap"])
def test_missing_bag(tmp_path, name):
    _raises(tmp_path / name, "bag not found")


def test_not_a_bag(tmp_path):
    (tmp_path / "d").mkdir()
    _raises(tmp_path / "d", "no metadata.yaml")
    (tmp_path / "x.txt").write_text("hello")
    _raises(tmp_path / "x.txt", "not a ROS bag")
    (tmp_path / "e.bag").write_bytes(b"")
    _raises(tmp_path / "e.bag", "empty")
    (tmp_path / "g.bag").write_bytes(b"garbage" * 100)
    _raises(tmp_path / "g.bag", "cannot read ROS1 bag")


@pytest.mark.parametrize("keep", [0.5, 0.999])
def test_truncated_ros1_bag(tmp_path, trial_data, keep):
    bag = _write(tmp_path / "t.bag", trial_data, "ros1", True)
    raw = bag.read_bytes()
    bag.write_bytes(raw[:int(len(raw) * keep)])
    _raises(bag, r"cannot read ROS1 bag \(truncated or corrupt\?\)")


@pytest.mark.parametrize("where", ["schema_page", "middle", "truncate"])
def test_corrupt_ros2_sqlite(tmp_path, trial_data, where):
    bag = _write(tmp_path / "t", trial_data, "ros2_sqlite3", True)
    db = bag / "t.db3"
    raw = bytearray(db.read_bytes())
    if where == "schema_page":
        raw[100:4096] = np.random.default_rng(0).integers(0, 256, 3996, dtype=np.uint8).tobytes()
    elif where == "middle":
        raw[len(raw) // 2:len(raw) // 2 + 8192] = b"\xff" * 8192
    else:
        raw = raw[:len(raw) // 2]
    db.write_bytes(bytes(raw))
    _raises(bag, r"cannot read ROS2 bag \(truncated or corrupt\?\)")


@pytest.mark.parametrize("keep", [0.5, 0.999])
def test_truncated_mcap(tmp_path, trial_data, keep):
    bag = _write(tmp_path / "t", trial_data, "ros2_mcap", True)
    f = bag / "t.mcap"
    raw = f.read_bytes()
    f.write_bytes(raw[:int(len(raw) * keep)])
    _raises(bag, r"cannot read ROS2 bag \(truncated or corrupt\?\)")
    _raises(f, r"cannot read ROS2 bag \(truncated or corrupt\?\)")


def test_ros2_storage_file_missing(tmp_path, trial_data):
    bag = _write(tmp_path / "t", trial_data, "ros2_mcap", True)
    (bag / "t.mcap").unlink()
    _raises(bag, "cannot read ROS2 bag")


@pytest.mark.parametrize("fmt", FORMATS)
def test_missing_image_topic_lists_topics_found(tmp_path, fmt):
    topics = _good_topics(fmt != "ros1")
    del topics[RIGHT]
    topics["/camera/other"] = topics[LEFT]
    bag = _bag(_bagpath(tmp_path, fmt), fmt, topics)
    err = _raises(bag, r"image topic /digit_right/image_raw \(digit_right\) is not in the bag; topics found:")
    for t in (LEFT, "/camera/other", WRENCH):
        assert t in str(err)
    assert "sensor_msgs/msg/Image" in str(err)


@pytest.mark.parametrize("fmt", FORMATS)
def test_missing_wrench_topic(tmp_path, fmt):
    topics = _good_topics(fmt != "ros1")
    del topics[WRENCH]
    bag = _bag(_bagpath(tmp_path, fmt), fmt, topics)
    err = _raises(bag, r"wrench topic /nano17/wrench is not in the bag; topics found:")
    assert LEFT in str(err) and RIGHT in str(err)


@pytest.mark.parametrize("fmt", FORMATS)
def test_wrong_message_type(tmp_path, fmt):
    ros2 = fmt != "ros1"
    topics = _good_topics(ros2)
    topics[LEFT] = ("std_msgs/msg/String", [(T0, _string(ros2))])
    bag = _bag(_bagpath(tmp_path, fmt), fmt, topics)
    _raises(bag, r"topic /digit_left/image_raw \(digit_left\) has type std_msgs/msg/String, expected "
                 r"sensor_msgs/msg/Image or sensor_msgs/msg/CompressedImage")

    topics = _good_topics(ros2)
    topics[WRENCH] = (ri.IMAGE, topics[LEFT][1])
    bag = _bag(_bagpath(tmp_path, fmt, "w"), fmt, topics)
    _raises(bag, r"topic /nano17/wrench \(wrench\) has type sensor_msgs/msg/Image, "
                 r"expected geometry_msgs/msg/WrenchStamped")


@pytest.mark.parametrize("fmt", FORMATS)
def test_unsupported_encoding(tmp_path, fmt):
    ros2 = fmt != "ros1"
    topics = _good_topics(ros2)
    px = np.zeros((4, 5, 4), np.uint8)
    topics[RIGHT][1][2] = (T0 + 23, _image(ros2, T0 + 23, px, encoding="bgra8"))
    bag = _bag(_bagpath(tmp_path, fmt), fmt, topics)
    err = _raises(bag, r"\[/digit_right/image_raw message 2\]: unsupported image encoding 'bgra8'")
    assert err.record == "/digit_right/image_raw message 2"


@pytest.mark.parametrize("fmt", FORMATS)
def test_image_data_size_mismatch(tmp_path, fmt):
    ros2 = fmt != "ros1"
    topics = _good_topics(ros2)
    px = _frames(1, 0, 6, 8)[0]
    short = px.reshape(-1)[:-3]
    topics[LEFT][1][1] = (T0 + 10, _image(ros2, T0 + 10, px, data=short))
    bag = _bag(_bagpath(tmp_path, fmt), fmt, topics)
    _raises(bag, r"\[/digit_left/image_raw message 1\]: image data has 141 bytes, expected height\*step = 6\*24 = 144")

    topics = _good_topics(ros2)
    topics[LEFT][1][0] = (T0, _image(ros2, T0, px, step=20, data=np.zeros(6 * 20, np.uint8)))
    bag = _bag(_bagpath(tmp_path, fmt, "s"), fmt, topics)
    _raises(bag, r"\[/digit_left/image_raw message 0\]: step 20 is shorter than a row of 8 bgr8 pixels")


@pytest.mark.parametrize("fmt", FORMATS)
def test_empty_topics(tmp_path, fmt):
    topics = _good_topics(fmt != "ros1")
    topics[RIGHT] = (ri.IMAGE, [])
    bag = _bag(_bagpath(tmp_path, fmt), fmt, topics)
    _raises(bag, r"topic /digit_right/image_raw \(digit_right\) has no messages")

    topics = _good_topics(fmt != "ros1")
    topics[WRENCH] = (ri.WRENCH_STAMPED, [])
    bag = _bag(_bagpath(tmp_path, fmt, "w"), fmt, topics)
    _raises(bag, r"topic /nano17/wrench \(wrench\) has no messages")


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("dup", [False, True], ids=["backwards", "duplicate"])
def test_header_stamps_must_increase(tmp_path, fmt, dup):
    ros2 = fmt != "ros1"
    px = _frames(4, 0, 6, 8)
    stamps = [T0, T0 + 10, T0 + 10 if dup else T0 + 5, T0 + 30]
    topics = _good_topics(ros2)
    # bag receive times increase: only the header stamps are out of order
    topics[LEFT] = (ri.IMAGE, [(T0 + 10 * k, _image(ros2, s, px[k], seq=k)) for k, s in enumerate(stamps)])
    bag = _bag(_bagpath(tmp_path, fmt), fmt, topics)
    word = "duplicates" if dup else "goes back from"
    err = _raises(bag, rf"\[/digit_left/image_raw message 2\]: header stamp {stamps[2]} ns {word} {T0 + 10} ns")
    assert err.record == "/digit_left/image_raw message 2"

    topics = _good_topics(ros2)
    topics[WRENCH] = (ri.WRENCH_STAMPED, [(T0 + 10 * k, _wrench(ros2, s, seq=k)) for k, s in enumerate(stamps)])
    bag = _bag(_bagpath(tmp_path, fmt, "w"), fmt, topics)
    _raises(bag, rf"\[/nano17/wrench message 2\]: header stamp .* {word}")


@pytest.mark.parametrize("fmt", FORMATS)
def test_unreadable_compressed_images(tmp_path, fmt):
    ros2 = fmt != "ros1"
    ok, png = cv2.imencode(".png", _frames(1, 0, 6, 8)[0])
    png = png.tobytes()
    topics = _good_topics(ros2)
    topics[LEFT] = (ri.COMPRESSED_IMAGE, [(T0 + k, _compressed(ros2, T0 + k, png, seq=k)) for k in range(3)])
    topics[LEFT][1][1] = (T0 + 1, _compressed(ros2, T0 + 1, b"definitely not an image" * 3))
    bag = _bag(_bagpath(tmp_path, fmt), fmt, topics)
    _raises(bag, r"\[/digit_left/image_raw message 1\]: compressed image is not readable png/jpeg data")

    # valid magic, damaged body: found when the frame is loaded
    broken = png[:40] + b"\x00" * (len(png) - 40)
    topics[LEFT][1][1] = (T0 + 1, _compressed(ros2, T0 + 1, broken))
    bag = _bag(_bagpath(tmp_path, fmt, "b"), fmt, topics)
    trial = ri.read_ros_trial(bag, META)
    assert trial.frames["digit_left"].load(0).shape == (6, 8, 3)
    _raises(bag, r"\[/digit_left/image_raw message 1\]: cannot decode compressed image \(format 'png'",
            lambda: trial.frames["digit_left"].load(1))

    # a format the importer does not decode
    topics[LEFT][1][1] = (T0 + 1, _compressed(ros2, T0 + 1, png, fmt="tiff"))
    bag = _bag(_bagpath(tmp_path, fmt, "f"), fmt, topics)
    _raises(bag, r"\[/digit_left/image_raw message 1\]: compressed image is not readable png/jpeg data "
                 r"\(format 'tiff'")


@pytest.mark.parametrize("fmt", ["ros1", "ros2_sqlite3"])
def test_image_transport_format_strings(tmp_path, fmt):
    """compressed_image_transport writes formats like 'rgb8; jpeg compressed bgr8' (data is BGR)."""
    ros2 = fmt != "ros1"
    px = _frames(2, 4, 16, 24)
    topics = _good_topics(ros2)
    pngs = [cv2.imencode(".png", p)[1].tobytes() for p in px]
    topics[RIGHT] = (ri.COMPRESSED_IMAGE, [(T0 + k, _compressed(ros2, T0 + k, pngs[k], "bgr8; png compressed bgr8"))
                                           for k in range(2)])
    jpg = cv2.imencode(".jpg", px[0], [cv2.IMWRITE_JPEG_QUALITY, 98])[1].tobytes()
    topics[LEFT] = (ri.COMPRESSED_IMAGE, [(T0, _compressed(ros2, T0, jpg, "rgb8; jpeg compressed bgr8"))])
    trial = ri.read_ros_trial(_bag(_bagpath(tmp_path, fmt), fmt, topics), META)
    np.testing.assert_array_equal(trial.frames["digit_right"].load(1), px[1])
    assert np.abs(trial.frames["digit_left"].load(0).astype(int) - px[0]).mean() < 3


def test_corrupt_message_bytes(tmp_path, trial_data):
    """A message whose bytes do not deserialise is reported with its topic and index."""
    bag = tmp_path / "t.bag"
    from rosbags.rosbag1 import Writer
    store = STORES[False]
    good = _good_topics(False)
    with Writer(bag) as w:
        for topic, (msgtype, msgs) in good.items():
            conn = w.add_connection(topic, msgtype, typestore=store)
            for k, (t, msg) in enumerate(msgs):
                raw = bytes(store.serialize_ros1(msg, msgtype))
                w.write(conn, t, raw[:10] if (topic == WRENCH and k == 1) else raw)
    _raises(bag, r"\[/nano17/wrench message 1\]: cannot decode geometry_msgs/msg/WrenchStamped")


def test_non_finite_force(tmp_path):
    topics = _good_topics(True)
    topics[WRENCH][1][2] = (T0 + 14, _wrench(True, T0 + 14, (0.0, float("nan"), 1.0)))
    bag = _bag(tmp_path / "t", "ros2_mcap", topics)
    _raises(bag, r"\[/nano17/wrench message 2\]: force contains NaN or inf")


def test_topics_argument_is_checked(tmp_path, trial_data):
    bag = _write(tmp_path / "t.bag", trial_data, "ros1", True)
    with pytest.raises(ValueError, match="wrench"):
        ri.read_ros_trial(bag, META, {"digit_left": LEFT})
    with pytest.raises(ArgumentError, match=r"topics \(params.yaml tool_ingest.ros_topics\): topic names must be "
                                            r"distinct"):
        ri.read_ros_trial(bag, META, {"digit_left": LEFT, "digit_right": LEFT, "wrench": WRENCH})
