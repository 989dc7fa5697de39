"""Property-based tests (hypothesis) of the parsers: round trips, and "any bytes give a valid
parse or the reader's own error, never another exception"."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from tactilepipe.papillarray import messages as pa
from tactilepipe.studies import load_params      # every study's checks too: none may raise anything else
from tactilepipe.core.errors import ConfigError, InputError
from tactilepipe.papillarray.shards import ingest_bag
from tactilepipe.tool.formats.native_layout import TrialMeta, read_calibration, read_frame_index
from tactilepipe.tool.formats.public_layout import _parse_force
from tactilepipe.tool.formats.serial_log import read_serial_log

from support.bags import sensor_stream, write_ros1_bag
from support.project import REPO

FAST = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
SLOW = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def scratch(name: str, data: bytes) -> tuple[tempfile.TemporaryDirectory, Path]:
    tmp = tempfile.TemporaryDirectory()
    path = Path(tmp.name) / name
    path.write_bytes(data)
    return tmp, path


# --- PapillArray codec ------------------------------------------------------------------------------

finite32 = st.floats(-1e6, 1e6, allow_nan=False, width=32)


@st.composite
def sensor_streams(draw):
    n = draw(st.integers(1, 12))
    stamps = np.sort(draw(hnp.arrays(np.int64, n, elements=st.integers(0, 2**32 * 10**9 - 1))))
    return {
        "stamp_ns": stamps,
        "tus": draw(hnp.arrays(np.int64, n, elements=st.integers(-2**63, 2**63 - 1))),
        "disp": draw(hnp.arrays(np.float32, (n, 9, 3), elements=finite32)),
        "force": draw(hnp.arrays(np.float32, (n, 9, 3), elements=finite32)),
        "in_contact": draw(hnp.arrays(bool, (n, 9))),
        "slip_state": draw(hnp.arrays(np.int32, (n, 9))),
        "frame_id": draw(st.text(st.characters(min_codepoint=32, max_codepoint=126), max_size=12)),
    }


@FAST
@given(sensor_streams())
def test_sensor_state_codec_round_trips(s):
    raws = pa.encode_sensor_states(s["stamp_ns"], s["tus"], s["disp"], s["force"], s["in_contact"],
                                   s["slip_state"], frame_id=s["frame_id"])
    dec = pa.decode_sensor_states(raws)
    np.testing.assert_array_equal(dec["stamp_ns"], s["stamp_ns"])
    np.testing.assert_array_equal(dec["tus"], s["tus"])
    np.testing.assert_array_equal(dec["force"], s["force"])
    np.testing.assert_array_equal(dec["disp"], s["disp"])
    np.testing.assert_array_equal(dec["in_contact"], s["in_contact"])
    np.testing.assert_array_equal(dec["slip_state"], s["slip_state"])
    # and rosbags reads our bytes the same way (the generic decoder)
    generic = pa._decode_generic(raws)
    for key in dec:
        np.testing.assert_array_equal(generic[key], dec[key], err_msg=key)


@FAST
@given(st.lists(st.binary(max_size=400), min_size=1, max_size=4))
def test_sensor_state_decoder_on_any_bytes_decodes_or_raises_value_error(raws):
    try:
        dec = pa.decode_sensor_states(raws)
    except ValueError as exc:
        assert str(exc).startswith("record ")
    else:
        assert len(dec["stamp_ns"]) == len(raws)


@FAST
@given(sensor_streams(), st.data())
def test_sensor_state_decoder_on_mutated_messages(s, data):
    raws = pa.encode_sensor_states(s["stamp_ns"], s["tus"], s["disp"], s["force"], s["in_contact"], s["slip_state"])
    k = data.draw(st.integers(0, len(raws) - 1))
    raw = bytearray(raws[k])
    for _ in range(data.draw(st.integers(1, 4))):
        raw[data.draw(st.integers(0, len(raw) - 1))] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(0, len(raw)))
    raws[k] = bytes(raw[:cut])
    try:
        pa.decode_sensor_states(raws)
    except ValueError as exc:
        assert str(exc).startswith("record ")


@FAST
@given(st.lists(st.binary(max_size=200), min_size=1, max_size=4))
def test_pose_decoder_on_any_bytes_decodes_or_raises_value_error(raws):
    try:
        stamps, pos = pa.decode_pose_stamped(raws)
    except ValueError:
        return
    assert len(stamps) == len(pos) == len(raws)


@SLOW
@given(st.data())
def test_a_damaged_papillarray_bag_ingests_or_is_an_input_error(small_bag_bytes, data):
    raw = bytearray(small_bag_bytes)
    for _ in range(data.draw(st.integers(1, 8))):
        raw[data.draw(st.integers(0, len(raw) - 1))] = data.draw(st.integers(0, 255))
    if data.draw(st.booleans()):
        raw = raw[:data.draw(st.integers(0, len(raw)))]
    tmp, bag = scratch("b.bag", bytes(raw))
    with tmp:
        out = Path(tmp.name) / "out" / "s.parquet"
        try:
            ingest_bag(bag, out)
        except InputError as exc:
            assert exc.path == str(bag)
            assert not out.exists()
        assert not list(Path(tmp.name).rglob("*.tmp"))


@pytest.fixture(scope="module")
def small_bag_bytes(tmp_path_factory) -> bytes:
    s = sensor_stream(n=6, seed=9)
    raws = pa.encode_sensor_states(s["stamp_ns"], s["tus"], s["disp"], s["force"], s["in_contact"], s["slip_state"])
    pose = pa.encode_pose_stamped(s["stamp_ns"][:3], np.zeros((3, 3)))
    bag = write_ros1_bag(tmp_path_factory.mktemp("bag") / "small.bag", {
        "/hub_0/sensor_0": (pa.SENSOR_STATE, s["stamp_ns"].tolist(), raws),
        "/tool_pose": (pa.POSE_STAMPED, s["stamp_ns"][:3].tolist(), pose)})
    return bag.read_bytes()


# --- the Arduino serial log --------------------------------------------------------------------------

@st.composite
def serial_samples(draw):
    n = draw(st.integers(1, 40))
    ms = sorted(draw(st.sets(st.integers(0, 2**32 - 1), min_size=n, max_size=n)))
    counts = draw(hnp.arrays(np.int64, (n, 6), elements=st.integers(0, 1023)))
    start = draw(st.integers(0, 2**62))
    return start, np.asarray(ms, np.int64), counts


@FAST
@given(serial_samples(), st.sampled_from(["\n", "\r\n"]))
def test_serial_log_round_trips(sample, newline):
    start, ms, counts = sample
    text = newline.join([f"# start_host_ns={start}"] + [",".join(map(str, [t, *c])) for t, c in zip(ms, counts)])
    tmp, path = scratch("force.log", (text + newline).encode())
    rails = ((counts == 0) | (counts == 1023)).any(axis=1)    # saturated samples: dropped and counted
    with tmp:
        if rails.all():
            with pytest.raises(InputError, match="at the ADC rails"):
                read_serial_log(path)
            return
        log = read_serial_log(path)
    assert log.start_host_ns == start and dict(log.drops) == ({"ADC saturated": int(rails.sum())} if rails.any() else {})
    np.testing.assert_array_equal(log.arduino_ms, ms[~rails])
    np.testing.assert_array_equal(log.counts, counts[~rails])


@FAST
@given(st.binary(max_size=600), st.booleans())
def test_serial_log_on_any_bytes_parses_or_is_an_input_error(data, with_header):
    if with_header:
        data = b"# start_host_ns=1000\n" + data
    tmp, path = scratch("force.log", data)
    with tmp:
        try:
            log = read_serial_log(path)
        except InputError as exc:
            assert exc.path == str(path)
            return
    assert len(log.arduino_ms) == len(log.counts) == len(log.line_numbers) > 0
    assert (np.diff(log.arduino_ms) > 0).all() and ((0 <= log.counts) & (log.counts <= 1023)).all()


line_chars = st.text(st.sampled_from("0123456789,-+_ .e\x00\xff\t"), max_size=40)


@FAST
@given(st.lists(line_chars, min_size=1, max_size=30))
def test_serial_log_on_number_like_lines_parses_or_is_an_input_error(lines):
    tmp, path = scratch("force.log", ("# start_host_ns=5\n" + "\n".join(lines)).encode("latin-1"))
    with tmp:
        try:
            log = read_serial_log(path)
        except InputError:
            return
    kept = len(log.arduino_ms)
    assert kept + sum(log.drops.values()) == len(lines)        # every line kept or counted


# --- frames.csv, .cal, meta.json, public force files, params.yaml -------------------------------------

@FAST
@given(st.binary(max_size=300) | st.text(st.sampled_from("frame,host_ns0123456789-\n\r_ x"), max_size=120)
       .map(str.encode))
def test_frame_index_on_any_bytes_parses_or_is_an_input_error(data):
    tmp = tempfile.TemporaryDirectory()
    with tmp:
        (Path(tmp.name) / "frames.csv").write_bytes(data)
        try:
            stamps = read_frame_index(tmp.name)
        except InputError:
            return
    assert stamps.dtype == np.int64 and (np.diff(stamps) > 0).all()


cal_values = st.text(st.sampled_from("0123456789.-e naif+"), max_size=30)


@FAST
@given(st.binary(max_size=300) | st.lists(cal_values, min_size=6, max_size=6).map(
    lambda rows: ("<FTSensor><Calibration>" + "".join(
        f'<UserAxis Name="{a}" values="{v}"/>' for a, v in zip(("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"), rows))
        + "</Calibration></FTSensor>").encode()))
def test_calibration_on_any_bytes_parses_or_is_an_input_error(data):
    tmp, path = scratch("nano17.cal", data)
    with tmp:
        try:
            matrix = read_calibration(path)
        except InputError as exc:
            assert exc.path == str(path)
            return
    assert matrix.shape == (6, 6) and np.isfinite(matrix).all()


json_values = st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=8),
                           lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner,
                                                                                        max_size=3), max_leaves=8)
meta_like = st.fixed_dictionaries({}, optional={k: json_values for k in (
    "trial", "tool", "kind", "orientation_deg", "insertion_mm", "camera_fps", "serial_hz", "notes", "extra")})


@FAST
@given(meta_like | json_values)
def test_trial_meta_from_any_json_value_validates_or_is_an_input_error(raw):
    try:
        meta = TrialMeta.from_dict(raw, "meta.json")
    except InputError as exc:
        assert exc.path == "meta.json"
        return
    assert meta.kind in ("normal", "shear") and np.isfinite(meta.orientation_deg)


@FAST
@given(st.binary(max_size=120), st.sampled_from(["normal", "shear"]))
def test_public_force_file_on_any_bytes_parses_or_is_an_input_error(data, kind):
    tmp, path = scratch("force_data_0000.txt", data)
    with tmp:
        try:
            values = _parse_force(path, kind)
        except InputError as exc:
            assert exc.path == str(path)
            return
    assert np.isfinite(values).all() and len(values) == (1 if kind == "normal" else 3)


@SLOW
@given(st.binary(max_size=200) | st.text(max_size=200).map(str.encode))
def test_params_file_of_any_bytes_loads_or_is_a_config_error(data):
    tmp, path = scratch("params.yaml", data)
    with tmp:
        try:
            load_params(path)
        except ConfigError:
            pass


@SLOW
@given(st.dictionaries(st.sampled_from(["seed", "scale", "folds", "mlp", "scenes", "segment", "unknown"]),
                       json_values, max_size=3))
def test_params_overrides_of_any_shape_load_or_are_a_config_error(overrides):
    try:
        load_params(REPO / "params.yaml", overrides)
    except ConfigError:
        pass
