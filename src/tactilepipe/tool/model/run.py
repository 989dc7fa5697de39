"""Train one model variant on one split, predict its test set, and time it (one CLI stage)."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.core.atomic import write_json, write_parquet
from tactilepipe.core.errors import InputError
from tactilepipe.tool.scenes import LABEL_NORMALISATION, scene_label
from tactilepipe.tool.model.evaluate import evaluate
from tactilepipe.tool.data.loader import ToolFrames



def train_and_predict(scene: str, data_dir: Path, split_path: Path, out_dir: Path, run: dict, tp: dict, seed: int,
                      progress: bool = True) -> dict:
    """Train ``run`` (tool/runs.py run_definition: its variant's name and architecture, split name,
    depth, input size) with the ``tool_train`` settings ``tp`` on the split file ``split_path``."""
    from tactilepipe.tool.model.checkpoint import stale_checkpoint_reason
    from tactilepipe.tool.model.train import train
    from tactilepipe.tool.model.train_config import TrainConfig
    from tactilepipe.tool.model.inference import latency_ms, load_model, predict
    variant, depth, image_size = run["variant"]["name"], run["depth"], run["image_size"]
    architecture = {k: v for k, v in run["variant"].items() if k != "name"}
    label = scene_label(scene)
    normalise = LABEL_NORMALISATION[label]
    data = ToolFrames(data_dir, label).resized(image_size)
    split = json.loads(Path(split_path).read_text())
    if split.get("name") != run["split"]:
        raise InputError(split_path, f"split {split.get('name')!r}, but run {run['name']} trains on split {run['split']!r}")
    seed += split["repeat"]          # each repeat of a split draws its own model seed too
    cfg = TrainConfig.from_params(tp, variant=variant, architecture=architecture, depth=depth, image_size=image_size,
                                  normalise=normalise, seed=seed)
    # last.pt of an interrupted run resumes it; one made with other settings (the workflow re-runs
    # this job after a parameter change) or unreadable is set aside, and the run starts again
    stale = stale_checkpoint_reason(out_dir / "last.pt", cfg, split, data)
    if stale:
        print(f"{out_dir / 'last.pt'}: {stale}; training from the start", file=sys.stderr)
        (out_dir / "last.pt").unlink()
        (out_dir / "best.pt").unlink(missing_ok=True)
    summary = train(data, split, cfg, out_dir, progress=progress)
    model, _ = load_model(out_dir / "best.pt")
    test = np.asarray(split["test"])
    t0 = time.perf_counter()
    pred = predict(model, data, test, split["label_stats"], normalise)
    predict_s = time.perf_counter() - t0
    s = data.samples.iloc[test]
    table = pd.DataFrame({"index": test, "trial": s["trial"].to_numpy(), "tool": s["tool"].to_numpy(),
                          "pose": s["pose"].to_numpy(), "t_s": s["t_s"].to_numpy(),
                          "true": data.labels[test].astype(float), "pred": pred.astype(float)})
    write_parquet(out_dir / "predictions.parquet", table)
    result = {**evaluate(table), "variant": variant, "depth": depth, "image_size": image_size,
              "split": split["name"], "train_s": summary["train_wall_s"], "epochs": summary["epochs_run"],
              "best_epoch": summary["best_epoch"],
              "resumed_from_epoch": summary["resumed_from_epoch"], "parameters": summary["parameters"],
              "latency_ms": latency_ms(model, image_size, n=20), "predict_s": predict_s, "device": summary["device"],
              "kernels": summary["kernels"]}
    write_json(out_dir / "eval.json", result)
    # last.pt (weights + Adam state, 3x best.pt) only serves to resume an interrupted run
    (out_dir / "last.pt").unlink(missing_ok=True)
    return result
