"""How closely do a session's images time its force labels? (reads a built session's shards; no training)

An arrival-stamped trial's force is on the host clock; its images' own best lag against |F| is the
witness of that clock (tool/data/session_clock.py): a trial whose lag lies more than
``tool_sync.witness.max_lag_error_s`` from its session's median is left out. How late a trial's
stamps can be and still pass depends on how much clean trials' lags scatter. This prints that
scatter for the pipeline's estimator (the correlation of the change signal with |F|, as stored in
each shard's clock record) and for one that allows any monotone relation between them (the R² of
an isotonic fit of the change on |F| at each lag), over the pressing trials whose images judge.

    python studies/tool_models/study_image_lag.py [--shards results/default/tool/shards/sim-default]

About 10 s on the default session's shards (78 of its 96 pressing trials judge) on one core.
"""

from __future__ import annotations

import argparse
import glob

import cv2
import numpy as np
import pyarrow.parquet as pq
from sklearn.isotonic import IsotonicRegression

from tactilepipe.tool.data.clock_sync import STEP_S, _peak, change_signal
from tactilepipe.tool.data.ingest import read_shard_info


def _trial(path: str) -> tuple[dict, dict, np.ndarray, np.ndarray]:
    """The shard's record, each finger's (frame stamps, change signal), the force stamps and |F|."""
    table = pq.read_table(path).to_pandas()
    info = read_shard_info(path)
    fingers = {}
    for sensor, rows in table[table.row == "frame"].groupby("sensor"):
        rows = rows.sort_values("t_ns")
        grays = np.stack([cv2.imdecode(np.frombuffer(p, np.uint8), cv2.IMREAD_GRAYSCALE) for p in rows.png])
        fingers[sensor] = (rows.t_ns.to_numpy(), change_signal(grays))
    force = table[table.row == "force"].sort_values("t_ns")
    return info, fingers, force.t_ns.to_numpy(), np.linalg.norm(force[["fx", "fy", "fz"]].to_numpy(), axis=1)


def isotonic_lag(fingers: dict, force_ns: np.ndarray, mag: np.ndarray, lags: np.ndarray) -> float:
    """The lag (s) at which an isotonic fit of the change on |F| explains most of the change (mean
    of the fingers' R²), refined by a parabola through its neighbours as the pipeline's fit is."""
    ref = min(t[0] for t, _ in fingers.values())
    force_s = (force_ns - ref) / 1e9
    curves = []
    for stamps, change in fingers.values():
        frame_s = (stamps - ref) / 1e9
        curve = np.full(len(lags), -np.inf)
        for k, d in enumerate(lags):
            inside = (frame_s - d >= force_s[0]) & (frame_s - d <= force_s[-1])
            f, y = np.interp(frame_s[inside] - d, force_s, mag), change[inside]
            fit = IsotonicRegression().fit_transform(f, y)
            curve[k] = 1 - ((y - fit) ** 2).sum() / max(((y - y.mean()) ** 2).sum(), 1e-12)
        curves.append(curve)
    return _peak(lags, np.mean(curves, axis=0))[0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shards", default="results/default/tool/shards/sim-default")
    ap.add_argument("--window-s", type=float, default=0.3, help="isotonic lags searched: 0 to this (s)")
    args = ap.parse_args()
    lags = np.arange(0.0, args.window_s + STEP_S / 2, STEP_S)
    found = {"correlation (the pipeline's)": [], "isotonic fit": []}
    for path in sorted(glob.glob(f"{args.shards}/*.parquet")):
        info, fingers, force_ns, mag = _trial(path)
        images = info["clock"].get("images", {})
        if info["kind"] != "normal" or not images.get("usable") or not info["witness"]["metrics"].get("images_judge"):
            continue
        found["correlation (the pipeline's)"].append(float(images["refined_shift_s"]))
        found["isotonic fit"].append(isotonic_lag(fingers, force_ns, mag, lags))
    print(f"{len(found['isotonic fit'])} pressing trials whose images judge, in {args.shards}\n")
    print("| estimator | median lag (ms) | 1.4826 MAD (ms) | 90th percentile of the distance to the median (ms) | largest (ms) |")
    print("|---|---|---|---|---|")
    for name, values in found.items():
        x = np.asarray(values) * 1000
        dist = np.abs(x - np.median(x))
        print(f"| {name} | {np.median(x):.1f} | {1.4826 * np.median(dist):.1f} | {np.percentile(dist, 90):.1f} | {dist.max():.1f} |")


if __name__ == "__main__":
    main()
