"""Tool-scene data benchmarks, printed side by side in one run.

1. Simulator: rendered QVGA frames/s on one core (target >= 200).
2. Ingest frames/s (read PNG, grayscale, resize, re-encode, write the shard) against a bare
   OpenCV decode + resize loop over the same frames (target >= 70 % of it).
3. Training loader samples/s (memory-mapped decoded arrays) against a loader that decodes and
   resizes the original JPEG frames for every sample, as the public code of study 000 does
   (4 images per sample: both fingers, current and reference; target >= 10x).
4. `tactilepipe predict`: a recorded trial streamed pair by pair (decode, preprocess, model at
   batch 1) through the default-scale full model, in sustained frame pairs/s on 2 threads
   (target >= 30, the DIGIT frame rate used in study 000). The trained checkpoint
   results/default/tool_normal/models/full/best.pt is used when it exists; otherwise a freshly
   initialised model of the same variant, depth and input size (speed does not depend on weights).

Usage: python benchmarks/bench_tool.py [--trials N] [--size 64] [--small]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from bench_predict_load import untrained_checkpoint
from tactilepipe.core.config import load_params
from tactilepipe.tool import sim as tsim
from tactilepipe.tool.data.dataset import build_tool_dataset
from tactilepipe.tool.data.ingest import ingest_trial
from tactilepipe.tool.data.loader import ToolFrames
from tactilepipe.tool.formats.native_import import read_native_trial
from tactilepipe.tool.model.stream import stream_predictions

REPO = Path(__file__).resolve().parents[1]


def row(name: str, seconds: float, count: int, unit: str) -> float:
    rate = count / seconds
    print(f"{name:<58}{seconds:>9.2f}{rate:>12,.0f} {unit}")
    return rate


def render_fps(params: dict, n_frames: int = 300) -> float:
    """Rendered QVGA frames per second on one core (height field, shear, shading, noise; no PNG)."""
    trial = tsim.Trial(tsim.session_plan(params)[0], params)
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        trial.frame(0, 0)
        t = time.perf_counter()
        for i in range(n_frames):
            trial.frame(i % 2, i % trial.n_frames)
        return n_frames / (time.perf_counter() - t)
    finally:
        cv2.setNumThreads(threads)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=4)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--samples", type=int, default=2000)
    ap.add_argument("--small", action="store_true", help="one smoke-scale trial, 20 rendered frames, 100 samples: "
                    "a check that it runs")
    args = ap.parse_args()
    p = load_params(REPO / "params.yaml", {"scale": "smoke" if args.small else "default"})
    if args.small:
        args.trials, args.size, args.samples = 1, 32, 100

    print("\n== Simulator (one core)")
    fps = render_fps(p, 20 if args.small else 300)
    print(f"rendered QVGA frames/s: {fps:,.0f}  (target >= 200: {'met' if fps >= 200 else 'NOT met'})")

    with tempfile.TemporaryDirectory(prefix="tactilepipe-bench-tool-") as tmp:
        session = Path(tmp) / "sim"
        plan = [t for t in tsim.session_plan(p) if t.kind == "normal"][: args.trials]
        tsim.write_session_calibration(session, p)
        for spec in plan:
            tsim.write_trial(session, spec, p)
        trials = [session / spec.name for spec in plan]
        pngs = sorted(f for t in trials for f in t.glob("digit_*/frame_*.png"))

        print(f"\n== Ingest: {len(trials)} trials, {len(pngs)} frames -> {args.size} px, best of 2")
        print(f"{'reader':<58}{'seconds':>9}{'rate':>12}")
        best_bare = min(_timed(lambda: [cv2.resize(cv2.cvtColor(cv2.imread(str(f)), cv2.COLOR_BGR2GRAY),
                                                   (args.size, args.size), interpolation=cv2.INTER_AREA)
                                        for f in pngs]) for _ in range(2))
        best_ours = min(_timed(lambda: [ingest_trial(read_native_trial(t), Path(tmp) / "shards" / f"{t.name}.parquet",
                                                     args.size, p["tool_ingest"]) for t in trials]) for _ in range(2))
        bare = row("bare OpenCV loop (imread + gray + resize)", best_bare, len(pngs), "frames/s")
        ours = row("tactilepipe ingest (+ clock sync, PNG encode, Parquet)", best_ours, len(pngs), "frames/s")
        print(f"ingest / bare = {ours / bare:.0%}  (target >= 70 %: {'met' if ours >= 0.7 * bare else 'NOT met'})")

        shards = sorted((Path(tmp) / "shards").glob("*.parquet"))
        build_tool_dataset(shards, "normal", Path(tmp) / "data", p["tool_sync"])
        data = ToolFrames(Path(tmp) / "data", "fz")
        # the public code's layout: JPEG frames on disk, decoded and resized for every sample
        jpg_dir = Path(tmp) / "jpg"
        jpg_dir.mkdir()
        jpgs = []
        for k, f in enumerate(pngs):
            out = jpg_dir / f"{k:06d}.jpg"
            cv2.imwrite(str(out), cv2.imread(str(f)))
            jpgs.append(out)
        rng = np.random.default_rng(0)
        n = min(args.samples, len(data))
        idx = rng.permutation(len(data))[:n]
        pick = rng.integers(0, len(jpgs), (n, 4))

        import torch  # imported before timing: both loaders hand torch tensors to the model

        def jpeg_loader():
            batch = []
            for k in range(n):
                imgs = [cv2.resize(cv2.cvtColor(cv2.imread(str(jpgs[j])), cv2.COLOR_BGR2GRAY), (args.size, args.size))
                        for j in pick[k]]
                batch.append(np.stack(imgs))
                if len(batch) == 64 or k == n - 1:
                    torch.from_numpy(np.stack(batch)).float().div_(255.0)
                    batch = []

        def our_loader():
            for _ in data.batches(idx, 64, shuffle=True):
                pass

        our_loader()  # warm-up: page the memory map in once, as every epoch after the first finds it

        print(f"\n== Training loader: {n} samples of 4 x {args.size} px, batch 64")
        print(f"{'loader':<58}{'seconds':>9}{'rate':>12}")
        jpeg = row("decode + resize 4 JPEGs per sample (public code)", _timed(jpeg_loader), n, "samples/s")
        mine = row("tactilepipe ToolFrames (memory-mapped, decoded once)", _timed(our_loader), n, "samples/s")
        print(f"ours / JPEG loader = {mine / jpeg:.1f}x  (target >= 10x: {'met' if mine >= 10 * jpeg else 'NOT met'})")

        print("\n== predict: one recorded trial streamed at batch 1 (2 threads)")
        torch.set_num_threads(2)
        checkpoint = REPO / "results/default/tool_normal/models/full/best.pt"
        if not checkpoint.exists():
            checkpoint = untrained_checkpoint(p, Path(tmp) / "untrained.pt", p["tool_ingest"]["stored_size"])
        print(f"checkpoint: {checkpoint}")
        with open(Path(tmp) / "predictions.csv", "w") as sink:
            summary = stream_predictions(checkpoint, trials[0], "native", p, out=sink)
        rate = summary["sustained_pairs_per_s"]
        print(f"{summary['pairs']} pairs, median latency {summary['median_latency_ms']:.1f} ms, sustained {rate:.1f} pairs/s "
              f"(target >= 30: {'met' if rate >= 30 else 'NOT met'})")


def _timed(func) -> float:
    t0 = time.perf_counter()
    func()
    return time.perf_counter() - t0


if __name__ == "__main__":
    main()
