"""`tactilepipe predict`: stream a recorded trial through a trained model, pair by pair.

Each frame pair is preprocessed exactly as for training (tool/ingest.preprocess at the ingest size,
then the loader's area downscale to the model's input size), stacked with
the trial's first pair as the zero-force reference, and run at batch 1; the prediction and the
latency (preprocessing + model) are printed per pair, then a summary with the sustained rate.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import cv2
import numpy as np

from tactilepipe.tool.importers import open_trial
from tactilepipe.tool.ingest import preprocess
from tactilepipe.tool.sync import pair_frames


def stream_predictions(checkpoint: Path, trial: Path, fmt: str, p: dict, limit: int | None = None,
                       out=sys.stdout) -> dict:
    import torch
    from tactilepipe.tool.train import denormalise, load_model
    model, meta = load_model(checkpoint)
    model.eval()
    size = meta["image_size"]
    raw = open_trial(trial, fmt, p["tool_ingest"]["ros_topics"])
    left, right = raw.frames["digit_left"], raw.frames["digit_right"]
    period = float(np.median(np.diff(left.host_ns))) if len(left) > 1 else 1e9 / 30
    il, ir = pair_frames(left.host_ns, right.host_ns, int(period / 2))
    if limit:
        il, ir = il[:limit], ir[:limit]

    ingest_size = p["tool_ingest"]["image_size"]

    def prep(frames, i):
        # the training path exactly: ingest's preprocessing at the dataset size, then the loader's
        # area downscale to the model's size (ToolFrames.resized)
        img = preprocess(frames.load(int(i)), ingest_size)
        return img if ingest_size == size else cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA)

    ref = [prep(left, il[0]), prep(right, ir[0])]
    latencies, preds = [], []
    print("pair,t_s,prediction_n,latency_ms", file=out)
    t_start = time.perf_counter()
    with torch.no_grad():
        for k, (i, j) in enumerate(zip(il, ir)):
            t0 = time.perf_counter()
            x = np.stack([prep(left, i), ref[0], prep(right, j), ref[1]])[None].astype(np.float32) / 255.0
            y = model(torch.from_numpy(x)).reshape(-1).numpy()
            pred = float(np.asarray(denormalise(y, meta["label_stats"], meta["normalise"])).reshape(-1)[0])
            latencies.append((time.perf_counter() - t0) * 1000)
            preds.append(pred)
            t_s = (left.host_ns[i] - left.host_ns[il[0]]) / 1e9
            print(f"{k},{t_s:.3f},{pred:.3f},{latencies[-1]:.2f}", file=out)
    wall = time.perf_counter() - t_start
    summary = {"pairs": len(preds), "median_latency_ms": float(np.median(latencies)),
               "sustained_pairs_per_s": len(preds) / wall}
    print(f"# {summary['pairs']} frame pairs, median latency {summary['median_latency_ms']:.1f} ms, "
          f"sustained {summary['sustained_pairs_per_s']:.1f} pairs/s (decode + preprocess + model)", file=out)
    return summary

