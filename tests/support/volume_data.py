"""Volume-scene helpers: samples that follow the algebraic baseline formula exactly, with their folds;
a simulated lift written as a bag whose two sensors are on clocks apart."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.volume.folds import make_folds


def baseline_data(mu_true: float, p: dict, seed: int = 0) -> tuple[pd.DataFrame, list[dict]]:
    """Samples that follow the baseline formula exactly for mu_true (Fz varies independently)."""
    rng = np.random.default_rng(seed)
    rows = []
    for v in np.arange(0.0, 301.0, 50.0):
        for i in range(4):
            fz = 6.0 * (1 + 0.1 * rng.standard_normal(30))
            fy = (v + p["container_mass_g"]) * p["gravity"] / 1000.0 - mu_true * fz
            rows.append(pd.DataFrame({"lift": f"v{v:g}_{i}", "volume_ml": v, "set": "main", "fy0": fy, "fz0": fz}))
    data = pd.concat(rows, ignore_index=True)
    return data, make_folds(data.drop_duplicates("lift"), 3, 3, 1, seed=seed)


def write_lift_bag_offset(path, rec: dict, start_ns: int, offset_s: float, write_ros1_bag) -> None:
    """A simulated lift (``rec``: volume/simulate.simulate_lift's output) written as a bag whose
    sensor 1 stamps its messages ``offset_s`` later than sensor 0 (a second clock), with the
    tests' own rosbags writer."""
    from tactilepipe.papillarray import messages as pa
    stamps = start_ns + np.round(rec["t"] * 1e9).astype(np.int64)
    topics = {}
    for s in range(2):
        st = stamps + (int(round(offset_s * 1e9)) if s == 1 else 0)
        raws = pa.encode_sensor_states(st, (st - start_ns) // 1000, rec["disp"][:, s], rec["force"][:, s],
                                       rec["in_contact"][:, s], rec["slip"][:, s].astype(np.int32),
                                       frame_id=f"hub_0/sensor_{s}")
        topics[pa.sensor_topic(0, s)] = (pa.SENSOR_STATE, st.tolist(), raws)
    pose_stamps = start_ns + np.round(rec["pose_t"] * 1e9).astype(np.int64)
    pos = np.zeros((len(pose_stamps), 3))
    pos[:, 0], pos[:, 2] = 0.45, rec["pose_z"]
    topics["/tool_pose"] = (pa.POSE_STAMPED, pose_stamps.tolist(), pa.encode_pose_stamped(pose_stamps, pos))
    Path(path).unlink(missing_ok=True)                 # the writer never overwrites
    write_ros1_bag(path, topics)
