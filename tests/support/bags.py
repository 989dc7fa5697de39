"""Hand-made ROS1 bags, written with rosbags directly (not with the project's bagio, so bad inputs
are made independently of the code under test), and a small synthetic PapillArray stream."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rosbags.rosbag1 import Writer

from tactilepipe.papillarray import messages as pa


def write_ros1_bag(path: str | Path, topics: dict[str, tuple[str, list[int], list[bytes]]]) -> Path:
    """Write ``{topic: (msgtype, bag stamps, raw messages)}`` with rosbags directly (not with the
    project's bagio, so bad inputs are made independently of the code under test)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    store = pa.typestore()
    with Writer(path) as writer:
        for topic, (msgtype, stamps, raws) in topics.items():
            conn = writer.add_connection(topic, msgtype, typestore=store)
            for stamp, raw in zip(stamps, raws):
                writer.write(conn, int(stamp), raw)
    return path


def sensor_stream(n: int = 20, seed: int = 0, t0_ns: int = 1_767_225_600_000_000_000,
                  period_ns: int = 2_000_000) -> dict:
    """A small synthetic PapillArray stream (arguments of encode_sensor_states)."""
    rng = np.random.default_rng(seed)
    force = rng.normal(0.0, 1.0, (n, 9, 3)).astype(np.float32)
    return {"stamp_ns": t0_ns + period_ns * np.arange(n, dtype=np.int64),
            "tus": 1000 + 2000 * np.arange(n, dtype=np.int64),
            "disp": (force / 4.0).astype(np.float32), "force": force,
            "in_contact": rng.random((n, 9)) > 0.3,
            "slip_state": rng.integers(0, 3, (n, 9)).astype(np.int32)}
