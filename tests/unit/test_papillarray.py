"""PapillArray message codec: our NumPy encoder/decoder against rosbags' own ROS1 serialiser."""

from __future__ import annotations

import numpy as np
import pytest

from tactilepipe.papillarray import messages as pa


def _store():
    return pa.typestore()


def _rosbags_sensor_state(stamp_ns: int, force, disp, in_contact, slip_state, frame_id="",
                          pillar_frame_ids=None, seq=0, tus=0, n_pillars=9):
    """A SensorState built field by field with rosbags' message classes."""
    store = _store()
    Header, Time = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    Pillar, State = store.types[pa.PILLAR_STATE], store.types[pa.SENSOR_STATE]
    stamp = Time(sec=int(stamp_ns // 1_000_000_000), nanosec=int(stamp_ns % 1_000_000_000))
    pillar_frame_ids = pillar_frame_ids or [""] * n_pillars
    pillars = [Pillar(header=Header(seq=seq, stamp=stamp, frame_id=pillar_frame_ids[i]), id=i,
                      dX=float(disp[i, 0]), dY=float(disp[i, 1]), dZ=float(disp[i, 2]),
                      fX=float(force[i, 0]), fY=float(force[i, 1]), fZ=float(force[i, 2]),
                      in_contact=bool(in_contact[i]), slip_state=int(slip_state[i]))
               for i in range(n_pillars)]
    g = force[:n_pillars].sum(axis=0)
    t = pa.global_torques(force)
    return State(header=Header(seq=seq, stamp=stamp, frame_id=frame_id), tus=tus, pillars=pillars,
                 gfX=float(g[0]), gfY=float(g[1]), gfZ=float(g[2]),
                 gtX=float(t[0]), gtY=float(t[1]), gtZ=float(t[2]),
                 friction_est=0.0, target_grip_force=0.0, is_sd_active=False, is_ref_loaded=True,
                 is_contact=bool(np.any(in_contact)))


def _assert_decoded_equals_stream(dec: dict, s: dict, rows=slice(None)):
    np.testing.assert_array_equal(dec["stamp_ns"], s["stamp_ns"][rows])
    np.testing.assert_array_equal(dec["force"], s["force"][rows])
    np.testing.assert_array_equal(dec["disp"], s["disp"][rows])
    np.testing.assert_array_equal(dec["in_contact"], s["in_contact"][rows])
    np.testing.assert_array_equal(dec["slip_state"], s["slip_state"][rows])
    np.testing.assert_allclose(dec["global"][:, :3], s["force"][rows].sum(axis=1), rtol=1e-5, atol=1e-5)


@pytest.fixture
def stream(sensor_stream):
    return sensor_stream(n=12, seed=3)


@pytest.fixture
def encoded(stream):
    return pa.encode_sensor_states(stream["stamp_ns"], stream["tus"], stream["disp"], stream["force"],
                                   stream["in_contact"], stream["slip_state"],
                                   frame_id="hub_0/sensor_0", seq0=5)


# --- encoder against rosbags ------------------------------------------------------------------

def test_encoded_messages_deserialize_with_rosbags_to_the_same_values(stream, encoded):
    store = _store()
    for k, raw in enumerate(encoded):
        msg = store.deserialize_ros1(raw, pa.SENSOR_STATE)
        assert msg.header.seq == 5 + k
        assert msg.header.frame_id == "hub_0/sensor_0"
        assert msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec == stream["stamp_ns"][k]
        assert msg.tus == stream["tus"][k]
        assert len(msg.pillars) == 9
        for i, p in enumerate(msg.pillars):
            assert p.id == i
            assert p.header.stamp == msg.header.stamp
            assert (p.fX, p.fY, p.fZ) == tuple(float(v) for v in stream["force"][k, i])
            assert (p.dX, p.dY, p.dZ) == tuple(float(v) for v in stream["disp"][k, i])
            assert p.in_contact == bool(stream["in_contact"][k, i])
            assert p.slip_state == stream["slip_state"][k, i]
        # the driver's global force is the sum of the pillars, its torque their moment
        np.testing.assert_allclose([msg.gfX, msg.gfY, msg.gfZ], stream["force"][k].sum(axis=0), rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose([msg.gtX, msg.gtY, msg.gtZ], pa.global_torques(stream["force"][k].astype(np.float64)),
                                   rtol=1e-4, atol=1e-4)
        assert msg.is_contact == bool(stream["in_contact"][k].any())
        assert msg.is_ref_loaded is True


def test_rosbags_serialisation_is_byte_identical_to_ours(encoded):
    store = _store()
    for raw in encoded:
        msg = store.deserialize_ros1(raw, pa.SENSOR_STATE)
        assert store.serialize_ros1(msg, pa.SENSOR_STATE) == raw


def test_message_built_by_rosbags_serialises_like_ours(stream):
    store = _store()
    k = 4
    msg = _rosbags_sensor_state(int(stream["stamp_ns"][k]), stream["force"][k], stream["disp"][k],
                                stream["in_contact"][k], stream["slip_state"][k], frame_id="hub_0/sensor_0",
                                seq=k, tus=int(stream["tus"][k]))
    ours = pa.encode_sensor_states(stream["stamp_ns"][k:k + 1], stream["tus"][k:k + 1], stream["disp"][k:k + 1],
                                   stream["force"][k:k + 1], stream["in_contact"][k:k + 1],
                                   stream["slip_state"][k:k + 1], frame_id="hub_0/sensor_0", seq0=k)[0]
    assert bytes(store.serialize_ros1(msg, pa.SENSOR_STATE)) == ours


# --- decoder ----------------------------------------------------------------------------------

def test_fast_decoder_equals_generic_decoder(stream, encoded, monkeypatch):
    calls = []
    real_generic = pa._decode_generic
    monkeypatch.setattr(pa, "_decode_generic", lambda raws: calls.append(len(raws)) or real_generic(raws))
    fast = pa.decode_sensor_states(encoded)
    assert calls == []                      # the uniform driver layout takes the NumPy path
    generic = real_generic(encoded)
    assert fast.keys() == generic.keys()
    for key in fast:
        assert fast[key].dtype == generic[key].dtype, key
        assert fast[key].shape == generic[key].shape, key
        np.testing.assert_array_equal(fast[key], generic[key], err_msg=key)
    _assert_decoded_equals_stream(fast, stream)
    assert fast["tus"].tolist() == stream["tus"].tolist()


def test_empty_stream_decodes_to_empty_arrays():
    dec = pa.decode_sensor_states([])
    assert dec["force"].shape == (0, 9, 3) and dec["stamp_ns"].shape == (0,) and dec["global"].shape == (0, 6)


def test_uniform_non_empty_pillar_frame_id_decodes_right(stream):
    store = _store()
    raws = [bytes(store.serialize_ros1(
        _rosbags_sensor_state(int(stream["stamp_ns"][k]), stream["force"][k], stream["disp"][k],
                              stream["in_contact"][k], stream["slip_state"][k], frame_id="hub_0/sensor_1",
                              pillar_frame_ids=[f"pillar_{i}" for i in range(9)], seq=k), pa.SENSOR_STATE))
        for k in range(len(stream["stamp_ns"]))]
    dec = pa.decode_sensor_states(raws)
    _assert_decoded_equals_stream(dec, stream)
    for key, value in pa._decode_generic(raws).items():
        np.testing.assert_array_equal(dec[key], value, err_msg=key)


@pytest.mark.parametrize("layout", ["mixed_pillar_frame_ids", "mixed_header_frame_ids", "pillar_fid_only_later"])
def test_irregular_layouts_fall_back_to_generic_and_decode_right(stream, layout, monkeypatch):
    """Messages that do not share one byte layout are decoded one by one through rosbags."""
    store = _store()
    n = len(stream["stamp_ns"])
    raws = []
    for k in range(n):
        if layout == "mixed_pillar_frame_ids":        # pillar frame_ids of different lengths in a message
            kwargs = {"pillar_frame_ids": ["p" * (i % 3) for i in range(9)]}
        elif layout == "mixed_header_frame_ids":      # messages of different lengths
            kwargs = {"frame_id": "s" * (k % 4)}
        else:                                         # the first message is regular, later ones are not
            kwargs = {"pillar_frame_ids": [""] * 9 if k == 0 else ["x"] * 9}
        msg = _rosbags_sensor_state(int(stream["stamp_ns"][k]), stream["force"][k], stream["disp"][k],
                                    stream["in_contact"][k], stream["slip_state"][k], seq=k, **kwargs)
        raws.append(bytes(store.serialize_ros1(msg, pa.SENSOR_STATE)))
    calls = []
    real_generic = pa._decode_generic
    monkeypatch.setattr(pa, "_decode_generic", lambda r: calls.append(len(r)) or real_generic(r))
    dec = pa.decode_sensor_states(raws)
    assert calls == [n]
    _assert_decoded_equals_stream(dec, stream)


def test_same_size_but_different_layout_is_not_misread(stream):
    """Record 1 has the same byte length as record 0 but a longer header frame_id and a shorter
    pillar frame_id: the fast path must notice and not read shifted fields."""
    store = _store()
    a = _rosbags_sensor_state(int(stream["stamp_ns"][0]), stream["force"][0], stream["disp"][0],
                              stream["in_contact"][0], stream["slip_state"][0], frame_id="",
                              pillar_frame_ids=["a"] + [""] * 8)
    b = _rosbags_sensor_state(int(stream["stamp_ns"][1]), stream["force"][1], stream["disp"][1],
                              stream["in_contact"][1], stream["slip_state"][1], frame_id="b",
                              pillar_frame_ids=[""] * 9)
    raws = [bytes(store.serialize_ros1(m, pa.SENSOR_STATE)) for m in (a, b)]
    assert len(raws[0]) == len(raws[1])
    _assert_decoded_equals_stream(pa.decode_sensor_states(raws), stream, slice(0, 2))


@pytest.mark.parametrize("index, keep", [(0, 10), (0, -200), (7, -1), (7, -100), (11, -3)])
def test_truncated_message_raises_value_error_naming_the_record(encoded, index, keep):
    """keep > 0: only the first ``keep`` bytes survive (10: shorter than a ROS Header); keep < 0: cut the tail."""
    raws = list(encoded)
    raws[index] = raws[index][:keep]
    with pytest.raises(ValueError, match=rf"^record {index}:"):
        pa.decode_sensor_states(raws)


def test_trailing_garbage_raises_value_error(encoded):
    raws = list(encoded)
    raws[3] = raws[3] + b"\x00\x01"
    with pytest.raises(ValueError, match=r"^record 3:"):
        pa.decode_sensor_states(raws)


def test_wrong_pillar_count_raises_value_error(stream):
    store = _store()
    raws = [bytes(store.serialize_ros1(
        _rosbags_sensor_state(int(stream["stamp_ns"][k]), stream["force"][k], stream["disp"][k],
                              stream["in_contact"][k], stream["slip_state"][k], seq=k,
                              n_pillars=9 if k != 2 else 8), pa.SENSOR_STATE)) for k in range(4)]
    with pytest.raises(ValueError, match=r"^record 2: SensorState has 8 pillars, expected 9"):
        pa.decode_sensor_states(raws)


@pytest.mark.parametrize("field", ["header", "pillar", "pose"])
def test_corrupt_frame_id_length_in_first_record_raises_value_error(encoded, field):
    if field == "pose":
        raws = pa.encode_pose_stamped(10**18 + np.arange(3, dtype=np.int64), np.zeros((3, 3)))
        at, decode = 12, pa.decode_pose_stamped
    else:
        raws = list(encoded)
        fid_len = int.from_bytes(raws[0][12:16], "little")
        at = 12 if field == "header" else 16 + fid_len + 8 + 4 + 12
        decode = pa.decode_sensor_states
    raw = bytearray(raws[0])
    raw[at:at + 4] = (0xFFFFFFF0).to_bytes(4, "little")
    with pytest.raises(ValueError, match=r"^record 0:"):
        decode([bytes(raw)] + list(raws[1:]))


# --- pose -------------------------------------------------------------------------------------

def test_pose_codec_round_trips_through_rosbags():
    store = _store()
    rng = np.random.default_rng(1)
    stamps = 1_767_225_600_000_000_000 + 8_000_000 * np.arange(6, dtype=np.int64) + 17
    pos = rng.normal(size=(6, 3))
    raws = pa.encode_pose_stamped(stamps, pos, frame_id="base_link")
    for k, raw in enumerate(raws):
        msg = store.deserialize_ros1(raw, pa.POSE_STAMPED)
        assert msg.header.frame_id == "base_link"
        assert msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec == stamps[k]
        assert (msg.pose.position.x, msg.pose.position.y, msg.pose.position.z) == tuple(pos[k])
        assert (msg.pose.orientation.x, msg.pose.orientation.y, msg.pose.orientation.z,
                msg.pose.orientation.w) == (0.0, 0.0, 0.0, 1.0)
        assert bytes(store.serialize_ros1(msg, pa.POSE_STAMPED)) == raw
    got_t, got_p = pa.decode_pose_stamped(raws)
    np.testing.assert_array_equal(got_t, stamps)
    np.testing.assert_array_equal(got_p, pos)


def test_pose_decoder_generic_path_and_truncation():
    stamps = 10**18 + 1000 * np.arange(4, dtype=np.int64)
    pos = np.arange(12, dtype=float).reshape(4, 3)
    mixed = pa.encode_pose_stamped(stamps[:2], pos[:2], "a") + pa.encode_pose_stamped(stamps[2:], pos[2:], "base")
    got_t, got_p = pa.decode_pose_stamped(mixed)          # different lengths: message by message
    np.testing.assert_array_equal(got_t, stamps)
    np.testing.assert_array_equal(got_p, pos)
    bad = list(mixed)
    bad[3] = bad[3][:-5]
    with pytest.raises(ValueError, match=r"^record 3:"):
        pa.decode_pose_stamped(bad)
