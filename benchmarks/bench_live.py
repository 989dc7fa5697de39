"""`tactilepipe live`: sustained frame pairs per second and latency, on a quiet CPU and beside a
2-thread load, next to `predict` on the same frames.

The cameras are image sequences of a default-scale simulated pressing trial (in the sensor's own
orientation, repeated to 400 frames), played by `live` at the DIGIT's QVGA rate of 60 fps: the
code path of a device, with only the source string different (rig/cameras.py). The load is
bench_predict_load.py's: a second process multiplying matrices on 2 threads. The model is the
default full model (results/default/tool_normal/models/full/best.pt when it exists, else a freshly built
one of the same shape: speed does not depend on the weights). Target: the camera rate in pairs
per second, and at least 30 pairs/s under load, as `predict` gives.

Usage: python benchmarks/bench_live.py [--checkpoint results/default/tool_normal/models/full/best.pt] [--small]
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2

from bench_predict_load import LOAD, REPO, predict_rate, untrained_checkpoint
from tactilepipe.core.config import load_params
from tactilepipe.rig.cameras import MODES, from_layout
from tactilepipe.tool import sim as tsim

MODE = "qvga60"
FRAMES = 400


def live_run(checkpoint: Path, sources: dict, log: Path, loaded: bool, seconds: float = 60) -> dict:
    load = subprocess.Popen([sys.executable, "-c", LOAD.format(seconds=60)]) if loaded else None
    try:
        run = subprocess.run([sys.executable, "-m", "tactilepipe", "live", "--params", str(REPO / "params.yaml"),
                              "--checkpoint", str(checkpoint), "--left", sources["digit_left"], "--right",
                              sources["digit_right"], "--mode", MODE, "--seconds", str(seconds), "--log", str(log)],
                             capture_output=True, text=True, cwd=REPO)
    finally:
        if load is not None:
            load.kill()
            load.wait()
    if run.returncode:
        raise SystemExit(f"live failed ({run.returncode}): {run.stderr.strip()[-2000:]}")
    m = re.search(r"# (\d+) pairs in ([0-9.]+) s \(([0-9.]+) pairs/s\), median latency ([0-9.]+) ms "
                  r"\(compute ([0-9.]+) ms\); frames skipped \{'digit_left': (\d+), 'digit_right': (\d+)\}", run.stdout)
    return {"pairs": int(m.group(1)), "rate": float(m.group(3)), "latency": float(m.group(4)),
            "compute": float(m.group(5)), "skipped": int(m.group(6)) + int(m.group(7))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", default=str(REPO / "results/default/tool_normal/models/full/best.pt"),
                    help="the model to run (default: the default scene's full model, when built)")
    ap.add_argument("--small", action="store_true", help="a smoke-scale model and trial, 40 frames, 2 s, quiet "
                    "only: a check that it runs")
    args = ap.parse_args()
    p = load_params(REPO / "params.yaml", {"scale": "smoke"} if args.small else None)
    n_frames, seconds, settings = (40, 2, (False,)) if args.small else (FRAMES, 60, (False, True))
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        session = tmp / "sim"
        spec = next(s for s in tsim.session_plan(p) if s.kind == "normal")
        tsim.write_session_calibration(session, p)
        tsim.write_trial(session, spec, p)
        trial = session / spec.name
        sources = {}
        for sensor in ("digit_left", "digit_right"):
            frames = sorted((trial / sensor).glob("frame_*.png"))
            out = tmp / "cameras" / sensor
            out.mkdir(parents=True)
            for k in range(n_frames):
                cv2.imwrite(str(out / f"frame_{k:06d}.png"), from_layout(cv2.imread(str(frames[k % len(frames)]))))
            sources[sensor] = str(out / "frame_%06d.png")
        checkpoint = Path(args.checkpoint)
        if args.small or not checkpoint.exists():
            checkpoint = untrained_checkpoint(p, tmp / "untrained.pt")
        fps = MODES[MODE][2]
        print(f"checkpoint: {checkpoint}\ncameras: {n_frames} frames per finger at {fps} fps ({MODE}); "
              f"predict: trial {spec.name}")
        print(f"\n{'':<10}{'live pairs/s':>14}{'latency ms':>12}{'compute ms':>12}{'skipped':>9}"
              f"{'predict pairs/s':>17}")
        for loaded in settings:
            r = live_run(checkpoint, sources, tmp / "live.csv", loaded, seconds)
            ref = predict_rate(checkpoint, trial, None, loaded)
            print(f"{'loaded' if loaded else 'quiet':<10}{r['rate']:>14.1f}{r['latency']:>12.1f}{r['compute']:>12.1f}"
                  f"{r['skipped']:>9d}{ref:>17.1f}")
        print(f"target: {fps} pairs/s (the camera rate) quiet, >= 30 pairs/s loaded")


if __name__ == "__main__":
    main()
