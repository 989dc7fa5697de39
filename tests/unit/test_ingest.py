"""Bag -> shard ingest: a faithful round trip, and every kind of bad recording rejected with an
InputError that names the file and the problem, leaving no output behind (also through the CLI)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from tactilepipe.cli import main as cli
from tactilepipe.papillarray import messages as pa
from tactilepipe.papillarray.bagio import read_topics, write_bag
from tactilepipe.core.errors import InputError
from tactilepipe.papillarray.shards import GLOBAL_COLS, ingest_bag

SENSOR0, SENSOR1 = pa.sensor_topic(0, 0), pa.sensor_topic(0, 1)


# --- round trip -------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def shard_frame(sim_lifts):
    item = sim_lifts[2]
    return item, pq.read_table(item["shard"]).to_pandas()


def test_shard_has_every_column(shard_frame):
    _, df = shard_frame
    want = ["topic", "stamp_ns", "sensor", *GLOBAL_COLS, "tool_z"]
    for i in range(9):
        want += [f"f{a}{i}" for a in "xyz"] + [f"d{a}{i}" for a in "xyz"] + [f"contact{i}", f"slip{i}"]
    assert sorted(df.columns) == sorted(want)
    assert set(df["topic"]) == {SENSOR0, SENSOR1, "/tool_pose"}


@pytest.mark.parametrize("sensor", [0, 1])
def test_shard_rows_equal_the_simulator_output(shard_frame, smoke_params, sensor):
    item, df = shard_frame
    rec = item["rec"]
    rows = df[df["sensor"] == sensor].sort_values("stamp_ns")
    assert (rows["topic"] == pa.sensor_topic(0, sensor)).all()
    assert len(rows) == len(rec["t"])
    start = rows["stamp_ns"].iloc[0]
    np.testing.assert_allclose((rows["stamp_ns"] - start).to_numpy() / 1e9, rec["t"], atol=1e-9)
    for i in range(9):
        for j, ax in enumerate("xyz"):
            np.testing.assert_allclose(rows[f"f{ax}{i}"], rec["force"][:, sensor, i, j], rtol=1e-6, atol=1e-6)
            np.testing.assert_allclose(rows[f"d{ax}{i}"], rec["disp"][:, sensor, i, j], rtol=1e-6, atol=1e-6)
        np.testing.assert_array_equal(rows[f"contact{i}"].astype(bool), rec["in_contact"][:, sensor, i])
    # the global force the driver publishes is the sum of the 9 pillars
    for ax in "xyz":
        pillars = rows[[f"f{ax}{i}" for i in range(9)]].to_numpy(np.float64).sum(axis=1)
        np.testing.assert_allclose(rows[f"gf{ax}"], pillars, atol=1e-5)
    assert rows["tool_z"].isna().all()


def test_shard_pose_rows(shard_frame):
    item, df = shard_frame
    rec = item["rec"]
    pose = df[df["topic"] == "/tool_pose"].sort_values("stamp_ns")
    assert len(pose) == len(rec["pose_t"])
    assert pose["sensor"].isna().all()
    np.testing.assert_array_equal(pose["tool_z"].to_numpy(), rec["pose_z"])
    assert pose[["gfx", "fx4"]].isna().all().all()


def test_ingest_reports_counts(tmp_path, good_bag):
    info = ingest_bag(good_bag, tmp_path / "deep" / "dir" / "s.parquet")
    assert info["sensors"] == [0, 1] and info["pose"] is True
    assert info["messages"] == pq.read_metadata(tmp_path / "deep" / "dir" / "s.parquet").num_rows
    assert [p.name for p in (tmp_path / "deep" / "dir").iterdir()] == ["s.parquet"]


def test_bag_io_round_trip_and_topic_filter(tmp_path):
    stamps = [10**18 + k for k in range(5)]
    raws = pa.encode_pose_stamped(np.array(stamps), np.ones((5, 3)))
    write_bag(tmp_path / "p.bag", {"/tool_pose": (pa.POSE_STAMPED, stamps, raws)})
    got = read_topics(tmp_path / "p.bag", {"/tool_pose": pa.POSE_STAMPED, "/absent": pa.SENSOR_STATE})
    assert list(got) == ["/tool_pose"]
    assert got["/tool_pose"] == (stamps, raws)


# --- bad input ---------------------------------------------------------------------------------

def _stream_topics(s: dict, header_stamps=None, force=None, sensors=(0, 1)) -> dict:
    """Sensor topics of a synthetic stream; header stamps may differ from the bag (receive) stamps."""
    header = s["stamp_ns"] if header_stamps is None else header_stamps
    f = s["force"] if force is None else force
    raws = pa.encode_sensor_states(header, s["tus"], s["disp"], f, s["in_contact"], s["slip_state"])
    return {pa.sensor_topic(0, k): (pa.SENSOR_STATE, s["stamp_ns"].tolist(), raws) for k in sensors}


def _make_bad(kind: str, d: Path, good: Path, write, stream) -> tuple[Path, str]:
    """Write a bad recording of the given kind; return it and a regex of the expected problem."""
    bag = d / f"{kind}.bag"
    s = stream(n=30, seed=1)
    if kind == "truncated":
        raw = good.read_bytes()
        bag.write_bytes(raw[: len(raw) // 2])
        return bag, "cannot read ROS1 bag"
    if kind == "random_bytes":
        bag.write_bytes(np.random.default_rng(0).bytes(20000))
        return bag, "cannot read ROS1 bag"
    if kind == "overwritten_middle":
        raw = bytearray(good.read_bytes())
        mid = len(raw) // 2
        raw[mid:mid + 4096] = np.random.default_rng(1).bytes(4096)
        bag.write_bytes(bytes(raw))
        return bag, "cannot read ROS1 bag|cannot decode"
    if kind == "empty":
        bag.write_bytes(b"")
        return bag, "bag file is empty"
    if kind == "missing":
        return bag, "bag file not found"
    if kind == "not_a_bag":
        bag.write_text("#ROSBAG V2.0\nthis is a text file, not a bag\n")
        return bag, "cannot read ROS1 bag"
    store = pa.typestore()
    String = store.types["std_msgs/msg/String"]
    chatter = [bytes(store.serialize_ros1(String(data=f"hello {k}"), "std_msgs/msg/String")) for k in range(3)]
    if kind == "unrelated_topic":
        write(bag, {"/chatter": ("std_msgs/msg/String", [10**18 + k for k in range(3)], chatter)})
        return bag, r"no PapillArray messages: expected topics \['/hub_0/sensor_0', '/hub_0/sensor_1'\]"
    if kind == "wrong_sensor_type":
        topics = _stream_topics(s, sensors=(0,))
        topics[SENSOR1] = ("std_msgs/msg/String", [10**18 + k for k in range(3)], chatter)
        write(bag, topics)
        return bag, (r"\[?topic /hub_0/sensor_1 has type std_msgs/msg/String, "
                     r"expected papillarray_ros_v2/msg/SensorState")
    if kind == "wrong_pose_type":
        topics = _stream_topics(s)
        topics["/tool_pose"] = ("std_msgs/msg/String", [10**18 + k for k in range(3)], chatter)
        write(bag, topics)
        return bag, "topic /tool_pose has type std_msgs/msg/String"
    if kind in ("nan_force", "inf_force"):
        f = s["force"].copy()
        f[17, 4, 1] = np.nan if kind == "nan_force" else np.inf
        topics = _stream_topics(s, sensors=(0,))
        topics.update(_stream_topics(s, force=f, sensors=(1,)))
        write(bag, topics)
        return bag, r"\[/hub_0/sensor_1 message 17\]: force values are NaN or inf"
    if kind == "inf_global_only":      # pillars finite, but the published global force is not
        raws = pa.encode_sensor_states(s["stamp_ns"], s["tus"], s["disp"], s["force"], s["in_contact"], s["slip_state"])
        msg = store.deserialize_ros1(raws[9], pa.SENSOR_STATE)
        msg.gfY = float("inf")
        raws[9] = bytes(store.serialize_ros1(msg, pa.SENSOR_STATE))
        write(bag, {SENSOR0: (pa.SENSOR_STATE, s["stamp_ns"].tolist(), raws)})
        return bag, r"\[/hub_0/sensor_0 message 9\]: force values are NaN or inf"
    if kind == "nan_pose":
        topics = _stream_topics(s)
        pos = np.zeros((5, 3))
        pos[3, 2] = np.nan
        stamps = s["stamp_ns"][:5]
        topics["/tool_pose"] = (pa.POSE_STAMPED, stamps.tolist(), pa.encode_pose_stamped(stamps, pos))
        write(bag, topics)
        return bag, r"\[/tool_pose\]: pose contains NaN or inf"
    if kind == "duplicated_stamp":
        header = s["stamp_ns"].copy()
        header[12] = header[11]
        write(bag, _stream_topics(s, header_stamps=header, sensors=(0,)))
        return bag, r"\[/hub_0/sensor_0 message 12\]: duplicated header timestamp"
    if kind == "out_of_order_stamp":
        header = s["stamp_ns"].copy()
        header[[20, 21]] = header[[21, 20]]           # the bag (receive) times stay in order
        write(bag, _stream_topics(s, header_stamps=header, sensors=(1,)))
        return bag, r"\[/hub_0/sensor_1 message 21\]: out-of-order header timestamp"
    if kind == "truncated_message":
        topics = _stream_topics(s, sensors=(0,))
        topics[SENSOR0][2][5] = topics[SENSOR0][2][5][:-40]
        write(bag, topics)
        return bag, r"\[/hub_0/sensor_0 record 5\]: cannot decode SensorState"
    if kind == "eight_pillars":
        raws = pa.encode_sensor_states(s["stamp_ns"], s["tus"], s["disp"], s["force"], s["in_contact"], s["slip_state"])
        msg = store.deserialize_ros1(raws[2], pa.SENSOR_STATE)
        msg.pillars = msg.pillars[:8]
        raws[2] = bytes(store.serialize_ros1(msg, pa.SENSOR_STATE))
        write(bag, {SENSOR1: (pa.SENSOR_STATE, s["stamp_ns"].tolist(), raws)})
        return bag, r"\[/hub_0/sensor_1 record 2\]: SensorState has 8 pillars, expected 9"
    if kind == "empty_sensor_topics":   # connections exist but hold no messages
        write(bag, {SENSOR0: (pa.SENSOR_STATE, [], []), SENSOR1: (pa.SENSOR_STATE, [], [])})
        return bag, "no PapillArray messages"
    raise AssertionError(kind)


BAD_KINDS = ["truncated", "random_bytes", "overwritten_middle", "empty", "missing", "not_a_bag",
             "unrelated_topic", "wrong_sensor_type", "wrong_pose_type", "nan_force", "inf_force",
             "inf_global_only", "nan_pose", "duplicated_stamp", "out_of_order_stamp", "truncated_message",
             "eight_pillars", "empty_sensor_topics"]


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")   # inf * 0 in the torques
@pytest.mark.parametrize("kind", BAD_KINDS)
def test_bad_bag_raises_input_error_and_writes_nothing(tmp_path, good_bag, write_ros1_bag, sensor_stream, kind):
    raw_dir, out_dir = tmp_path / "raw", tmp_path / "out"
    raw_dir.mkdir()
    out_dir.mkdir()
    bag, problem = _make_bad(kind, raw_dir, good_bag, write_ros1_bag, sensor_stream)
    shard = out_dir / "shard.parquet"
    with pytest.raises(InputError) as err:
        ingest_bag(bag, shard)
    msg = str(err.value)
    assert err.value.path == str(bag)
    assert msg.startswith(str(bag))
    assert re.search(problem, msg), msg
    assert list(out_dir.iterdir()) == []                  # no shard, no temporary
    assert not list(raw_dir.glob("*.tmp")) and not list(raw_dir.glob(".*.tmp"))


def test_bad_bag_leaves_an_existing_shard_untouched(tmp_path, good_bag):
    shard = tmp_path / "shard.parquet"
    ingest_bag(good_bag, shard)
    before = shard.read_bytes()
    bad = tmp_path / "bad.bag"
    bad.write_bytes(good_bag.read_bytes()[:5000])
    with pytest.raises(InputError, match="cannot read ROS1 bag"):
        ingest_bag(bad, shard)
    assert shard.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.bag", "shard.parquet"]


def test_corrupt_frame_id_length_in_bag_is_an_input_error(tmp_path, sensor_stream, write_ros1_bag):
    s = sensor_stream(n=10, seed=2)
    raws = pa.encode_sensor_states(s["stamp_ns"], s["tus"], s["disp"], s["force"], s["in_contact"], s["slip_state"])
    first = bytearray(raws[0])
    first[12:16] = (0xB9D0_0000).to_bytes(4, "little")     # as a random overwrite of the bag would do
    raws[0] = bytes(first)
    bag = write_ros1_bag(tmp_path / "corrupt.bag", {SENSOR0: (pa.SENSOR_STATE, s["stamp_ns"].tolist(), raws)})
    with pytest.raises(InputError, match=r"\[/hub_0/sensor_0 record 0\]"):
        ingest_bag(bag, tmp_path / "out" / "s.parquet")


# --- through the CLI ----------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["truncated", "missing", "empty", "nan_force", "wrong_sensor_type",
                                  "out_of_order_stamp"])
def test_cli_ingest_reports_one_line_and_exit_code_2(tmp_path, good_bag, write_ros1_bag, sensor_stream, capsys, kind):
    bag, problem = _make_bad(kind, tmp_path, good_bag, write_ros1_bag, sensor_stream)
    out = tmp_path / "out" / "shard.parquet"
    assert cli.main(["papillarray-ingest", str(bag), str(out)]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("tactilepipe papillarray-ingest: error: ")
    assert bag.name in lines[0] and re.search(problem, lines[0])
    assert "Traceback" not in captured.err + captured.out
    assert not out.exists() and not list(tmp_path.rglob("*.tmp"))


def test_cli_ingest_good_bag_prints_counts(tmp_path, good_bag, capsys):
    out = tmp_path / "shard.parquet"
    assert cli.main(["papillarray-ingest", str(good_bag), str(out)]) == 0
    assert '"sensors": [0, 1]' in capsys.readouterr().out
    assert out.exists()


def test_cli_ingest_rejects_a_bag_without_shard(tmp_path, good_bag, capsys):
    out = tmp_path / "a.parquet"
    rc = cli.main(["papillarray-ingest", str(good_bag), str(out), str(good_bag)])
    assert rc == 2
    assert "error" in capsys.readouterr().err
