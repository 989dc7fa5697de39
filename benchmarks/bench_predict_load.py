"""`tactilepipe predict` on a quiet CPU and beside a controlled 2-thread load, side by side.

The load is another process multiplying 512 x 512 matrices with torch on 2 threads for a bounded
time (what a training job or a second pipeline stage does to the cores). predict runs as the CLI
does (a fresh process, so OpenMP's wait policy applies), streaming one default-scale simulated
trial through the default full model (results/default/tool_normal/models/full/best.pt when it exists,
else a freshly initialised one of the same depth and input size: speed does not depend on the
weights). Each setting is run with params.yaml's `predict` group and with the former behaviour
(2 spinning threads) for comparison. Target: >= 30 pairs/s sustained under load (DIGIT's rate).

Usage: python benchmarks/bench_predict_load.py [--repeats 2] [--small]
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

from tactilepipe.core.config import load_params
from tactilepipe.tool import sim as tsim

REPO = Path(__file__).resolve().parents[1]
LOAD = """
import time, torch
torch.set_num_threads(2)
a = torch.randn(512, 512)
end = time.time() + {seconds}
while time.time() < end:
    a = torch.tanh(a @ a)
"""


def untrained_checkpoint(p: dict, path: Path, size: int | None = None) -> Path:
    """A checkpoint of a freshly initialised full model of ``p``'s depth, width and input size
    (``size``, default ``tool_train.image_size``), with the metadata the trainer writes."""
    import torch
    from tactilepipe.tool.model.network import build_model
    from tactilepipe.tool.model.checkpoint import CHECKPOINT_FORMAT
    from tactilepipe.tool.model.train_config import TrainConfig
    tt = p["tool_train"]
    size = size or tt["image_size"]
    cfg = TrainConfig.from_params(tt, variant="full", depth=tt["depth"], image_size=size, normalise="minmax",
                                  seed=p["seed"])
    # the model's shape as the trainer records it: without width and gate, a reader takes the
    # values of checkpoints made before they existed (the paper's width)
    meta = {"variant": "full", "depth": tt["depth"], "image_size": size, "gam_channel_gate": tt["gam_channel_gate"],
            "width": tt["width"], "normalise": "minmax", "label_stats": {"min": 0.0, "max": 30.0, "mean": 5.0, "std": 5.0}}
    model = build_model("full", tt["depth"], size, tt["gam_channel_gate"], tt["width"])
    torch.save({"format": CHECKPOINT_FORMAT, "model": model.state_dict(), "config": cfg.model_dump(),
                "meta": meta}, path)
    return path


def predict_rate(checkpoint: Path, trial: Path, override: dict | None, loaded: bool) -> float:
    load = subprocess.Popen([sys.executable, "-c", LOAD.format(seconds=60)]) if loaded else None
    try:
        cmd = [sys.executable, "-m", "tactilepipe", "predict", "--params", str(REPO / "params.yaml"),
               "--checkpoint", str(checkpoint), "--trial", str(trial)]
        if override:
            cmd += ["--override", json.dumps(override)]
        run = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO)
        if run.returncode:
            raise SystemExit(f"predict failed ({run.returncode}): {run.stderr.strip()[-2000:]}")
        out = run.stdout
    finally:
        if load is not None:
            load.kill()
            load.wait()
    return float(re.search(r"sustained ([0-9.]+) pairs/s", out).group(1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=2, help="runs per setting; the median is printed")
    ap.add_argument("--small", action="store_true", help="a smoke-scale trial and model, one run per setting, "
                    "the params.yaml setting only: a check that it runs")
    args = ap.parse_args()
    p = load_params(REPO / "params.yaml", {"scale": "smoke"} if args.small else None)
    if args.small:
        args.repeats = 1
    with tempfile.TemporaryDirectory() as tmp:
        session = Path(tmp) / "sim"
        spec = next(s for s in tsim.session_plan(p) if s.kind == "normal")
        tsim.write_session_calibration(session, p)
        tsim.write_trial(session, spec, p)
        checkpoint = REPO / "results/default/tool_normal/models/full/best.pt"
        if args.small or not checkpoint.exists():
            checkpoint = untrained_checkpoint(p, Path(tmp) / "untrained.pt")
        print(f"checkpoint: {checkpoint}\ntrial: {spec.name} ({p['simulate_tool']['frames_per_trial']} frames/finger)")
        settings = {f"params.yaml predict ({p['predict']['num_threads']} thread, {p['predict']['wait_policy']})": None,
                    "former: 2 threads, active wait": {"predict": {"num_threads": 2, "wait_policy": "active"}}}
        if args.small:
            settings = dict(list(settings.items())[:1])
        print(f"\n{'setting':<46}{'quiet':>12}{'loaded':>12}   (sustained pairs/s, median of {args.repeats})")
        for name, override in settings.items():
            rates = []
            for loaded in (False, True):
                runs = sorted(predict_rate(checkpoint, session / spec.name, override, loaded) for _ in range(args.repeats))
                rates.append(runs[len(runs) // 2])
            print(f"{name:<46}{rates[0]:>12.1f}{rates[1]:>12.1f}"
                  + (f"   target >= 30 loaded: {'met' if rates[1] >= 30 else 'NOT met'}" if override is None else ""))


if __name__ == "__main__":
    main()
