"""Study 000 on its own data (docs/reproduce_study_000.md): a checkpoint evaluated on a dataset,
and the tables that put our numbers beside the paper's.

- ``evaluate_checkpoint``: ours (best.pt) or the public code's (best_model_*.pth) over a split's
  test set or over every frame. Metrics on the full set of predictions, never averaged over
  batches. A public checkpoint predicts min-max-normalised normal force with the statistics of
  the whole data set (the public code takes them before its split), so those are used here; its
  shear head predicts N directly.
- ``protocol_table``: the full model under the public code's frame-level split (leaky, the
  paper's protocol) and under our trial split, beside the paper's MAE and R².
- ``published_table``: the published weights over every frame, labelled contaminated: they were
  trained on about 70 % of these frames, under a split nobody can redraw. A check that our
  preprocessing and key mapping match the authors', not a test result.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.core.atomic import write_json, write_parquet
from tactilepipe.core.errors import InputError
from tactilepipe.core.tables import write_table
from tactilepipe.tool.model.evaluate import evaluate
from tactilepipe.tool.data.loader import ToolFrames
from tactilepipe.tool.scenes import scene_label
from tactilepipe.tool.data.splits import label_stats

PUBLIC_IMAGE_SIZE = 224     # the public code resizes every frame to 224 x 224
PROTOCOLS = {   # run (results/<build>/<scene>/models/<run>) -> how the table names it
    "full_public_frame": "frame-level 70/15/15 split of the public code (leaky: the paper's protocol)",
    "full_trial": "whole trials per split (ours: no frame of a test trial is seen in training)",
}
CONTAMINATED = ("contaminated: the published weights were trained on about 70 % of these frames "
                "(frame-level split, unseeded, not recoverable); a check of preprocessing and key mapping, "
                "not a test result")


def evaluate_checkpoint(checkpoint: Path, data_dir: Path, scene: str, out_dir: Path, split_path: Path | None,
                        contaminated: bool, device: str = "cpu") -> dict:
    """eval.json and predictions.parquet in ``out_dir`` for the test set of ``split_path`` (None:
    every frame of the data set)."""
    from tactilepipe.tool.model.inference import load_model, predict
    label = scene_label(scene)
    data = ToolFrames(data_dir, label)
    model, meta = load_model(checkpoint, device=device, image_size=int(data.frames.shape[-1]))
    if meta.get("label") not in (None, label):
        raise InputError(checkpoint, f"a model of the {meta['label']} force cannot evaluate the {scene} scene")
    data = data.resized(meta["image_size"])
    if split_path is None:
        idx, frames = np.arange(len(data)), "all"
    else:
        idx, frames = np.asarray(json.loads(Path(split_path).read_text())["test"]), f"test set of {split_path}"
    stats, normalise = meta["label_stats"], meta["normalise"]
    if meta["source"] == "public":
        stats = label_stats(data.labels.astype(np.float64)) if label == "normal" else {"min": 0.0, "max": 1.0}
    pred = predict(model, data, idx, stats, normalise)
    s = data.samples.iloc[idx]
    table = pd.DataFrame({"index": idx, "trial": s["trial"].to_numpy(), "tool": s["tool"].to_numpy(),
                          "pose": s["pose"].to_numpy(), "t_s": s["t_s"].to_numpy(),
                          "true": data.labels[idx].astype(float), "pred": np.asarray(pred, float)})
    write_parquet(out_dir / "predictions.parquet", table)
    result = {**evaluate(table), "checkpoint": str(checkpoint), "source": meta["source"], "frames": frames,
              "depth": meta["depth"], "image_size": meta["image_size"], "gam_channel_gate": meta["gam_channel_gate"],
              "label_stats": stats, "contaminated": bool(contaminated)}
    if contaminated:
        result["note"] = CONTAMINATED
    if meta["source"] == "public" and meta["image_size"] != PUBLIC_IMAGE_SIZE:
        result["warning"] = (f"the public weights were trained on {PUBLIC_IMAGE_SIZE} px inputs, run here at "
                             f"{meta['image_size']} px (tool_ingest.stored_size): use the paper scale")
    write_json(out_dir / "eval.json", result)
    return result


def _paper_row(paper: dict) -> dict:
    return {"protocol": "paper (reported)", "split": "frame-level, unseeded", "leaky": True, "n": None,
            "mae_n": paper["mae_n"], "rmse_n": None, "r2": paper["r2"]}


def _whole_counts(table: pd.DataFrame) -> pd.DataFrame:
    table["n"] = pd.Series([None if pd.isna(v) else int(v) for v in table["n"]], dtype=object)
    return table


def protocol_table(evals: dict[str, Path], paper: dict, out_dir: Path) -> pd.DataFrame:
    """protocols.csv/.md and metrics.json: one row per run of PROTOCOLS, then the paper's."""
    rows = []
    for run, path in evals.items():
        e = json.loads(Path(path).read_text())
        rows.append({"protocol": PROTOCOLS[run], "split": e["split"], "leaky": e["split"] in ("frame", "public_frame"),
                     "n": e["n"], "mae_n": e["mae"], "rmse_n": e["rmse"], "r2": e["r2"]})
    table = _whole_counts(pd.DataFrame(rows + [_paper_row(paper)]))
    write_table(table, out_dir / "protocols", "Study 000, full model, normal force: our run under two protocols "
                                              "beside the paper (metrics on the full set of test predictions)")
    write_json(out_dir / "metrics.json", {r["split"]: {k: r[k] for k in ("n", "mae_n", "rmse_n", "r2")}
                                          for r in rows} | {"paper": paper})
    return table


def published_table(eval_path: Path, paper: dict, out_dir: Path) -> pd.DataFrame:
    """published.csv/.md: the published weights over every frame (contaminated) beside the paper."""
    e = json.loads(Path(eval_path).read_text())
    row = {"protocol": "published weights over every frame (contaminated)", "split": "none: every frame",
           "leaky": True, "n": e["n"], "mae_n": e["mae"], "rmse_n": e["rmse"], "r2": e["r2"]}
    table = _whole_counts(pd.DataFrame([row, _paper_row(paper)]))
    write_table(table, out_dir / "published", f"Published weights of study 000 over every frame. {CONTAMINATED}")
    return table
