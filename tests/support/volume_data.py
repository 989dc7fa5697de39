"""Volume-scene helpers: samples that follow the algebraic baseline formula exactly, with their folds;
a simulated lift written as a bag whose two sensors are on clocks apart; simulated lifts written
back to back into one bag, or cut, as a recording that is not one whole lift."""

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


def write_lifts_bag(path, recs: list[dict], start_ns: int, write_ros1_bag, keep_s: tuple = (0.0, None)) -> dict:
    """Simulated lifts (``recs``: volume/simulate.simulate_lift's outputs) recorded back to back in
    one bag (each starts one sample after the previous one ends), of which only the samples from
    ``keep_s[0]`` to ``keep_s[1]`` s are written (a recording started late or stopped early).
    Returns the joined recording (t, force, pose_t, pose_z) as written."""
    parts, pose_parts, t0 = [], [], 0.0
    for rec in recs:
        parts.append({k: rec[k] for k in ("force", "disp", "in_contact", "slip")} | {"t": rec["t"] + t0})
        pose_parts.append((rec["pose_t"] + t0, rec["pose_z"]))
        t0 += rec["t"][-1] + (rec["t"][1] - rec["t"][0])
    joined = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    pose_t, pose_z = (np.concatenate(x) for x in zip(*pose_parts))
    lo, hi = keep_s[0], np.inf if keep_s[1] is None else keep_s[1]
    rows, pose_rows = (joined["t"] >= lo) & (joined["t"] < hi), (pose_t >= lo) & (pose_t < hi)
    joined = {k: v[rows] for k, v in joined.items()} | {"pose_t": pose_t[pose_rows], "pose_z": pose_z[pose_rows]}
    write_lift_bag_offset(path, joined, start_ns, 0.0, write_ros1_bag)
    return joined
