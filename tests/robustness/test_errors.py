"""Every user-facing error is a TactilepipeError: a bad argument is an ArgumentError naming it, bad
data read from a file an InputError naming the file and the record; the CLI prints either as one
line (exit code 2), never a traceback."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

from tactilepipe.papillarray import messages as pa
from tactilepipe.core.errors import ArgumentError, InputError, TactilepipeError
from tactilepipe.core.metrics import r2_detail
from tactilepipe.papillarray.shards import DEFAULT_POSE_TOPIC, read_papillarray_bag

from support.project import REPO

SRC = REPO / "src"


def test_argument_error_is_a_tactilepipe_error_and_a_value_error():
    # the CLI prints it as one line; `except ValueError` (argparse, callers wrapping a decoder) still works
    assert issubclass(ArgumentError, TactilepipeError) and issubclass(ArgumentError, ValueError)
    with pytest.raises(ArgumentError, match=r"r2: 3 true values \(y_true\) but 2 predictions \(y_pred\)"):
        r2_detail([1.0, 2.0, 3.0], [1.0, 2.0])


def test_cli_bad_ros_topics_is_one_line_naming_the_parameter(tmp_path):
    """Two sensors on one topic passes the schema (any strings) and reaches read_ros_trial's check
    of the topic map, before the bag is opened: the bag need not exist, only its sidecar."""
    (tmp_path / "t.meta.json").write_text(json.dumps({"tool": "screwdriver_small", "kind": "normal",
                                                      "orientation_deg": 15.0, "insertion_mm": 12.5}))
    out = tmp_path / "t.parquet"
    override = {"tool_ingest": {"ros_topics": {"digit_left": "/cam", "digit_right": "/cam"}}}
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-m", "tactilepipe", "tool-ingest", str(tmp_path / "t.bag"),
                           "--format", "ros", "--out", str(out), "--params", str(REPO / "params.yaml"),
                           "--override", json.dumps(override)],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("tactilepipe tool-ingest: error: topics (params.yaml tool_ingest.ros_topics): "
                               "topic names must be distinct"), lines[0]
    assert "Traceback" not in proc.stderr
    assert not out.exists()


def test_checkpoint_with_bad_metadata_names_the_file(tmp_path):
    torch = pytest.importorskip("torch")
    from tactilepipe.tool.model.checkpoint import CHECKPOINT_FORMAT
    from tactilepipe.tool.model.inference import load_model
    ckpt = tmp_path / "best.pt"
    torch.save({"format": CHECKPOINT_FORMAT, "meta": {"variant": "tiny", "depth": 18, "image_size": 32},
                "config": {}, "model": {}}, ckpt)
    with pytest.raises(InputError, match=rf"^{re.escape(str(ckpt))}: metadata: unknown model variant 'tiny' "
                                         r"without its definition \(sensors, gam\): the names known without one "
                                         r"are full, no_ref"):
        load_model(ckpt)


def test_undecodable_pose_names_the_bag_and_the_record(tmp_path, sensor_stream, write_ros1_bag):
    """The decoder only has bytes (ArgumentError "record 2: ..."); the bag reader names the file."""
    s = sensor_stream(n=6, seed=3)
    raws = pa.encode_sensor_states(s["stamp_ns"], s["tus"], s["disp"], s["force"], s["in_contact"], s["slip_state"])
    poses = pa.encode_pose_stamped(s["stamp_ns"], np.zeros((6, 3)))
    poses[2] = poses[2][:-5]
    with pytest.raises(ArgumentError, match=r"^record 2: cannot decode PoseStamped"):
        pa.decode_pose_stamped(poses)
    bag = write_ros1_bag(tmp_path / "lift.bag", {
        pa.sensor_topic(0, 0): (pa.SENSOR_STATE, s["stamp_ns"].tolist(), raws),
        DEFAULT_POSE_TOPIC: (pa.POSE_STAMPED, s["stamp_ns"].tolist(), poses)})
    with pytest.raises(InputError, match=rf"^{re.escape(str(bag))} \[{DEFAULT_POSE_TOPIC} record 2\]: "
                                         r"cannot decode PoseStamped"):
        read_papillarray_bag(bag)
