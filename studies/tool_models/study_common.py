"""What the tool-scene studies (study_grasps.py, study_splits.py) share: their common arguments,
loading a built scene with its tactile-RMSE features (computed once), and per arm the refitted
baseline and a training run."""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tactilepipe.core.config import load_params
from tactilepipe.tool.model.evaluate import linear_fit_predictions, summarise, tactile_rmse_features
from tactilepipe.tool.data.loader import ToolFrames
from tactilepipe.tool.model.kernels import use_kernels
from tactilepipe.tool.model.run import train_and_predict
from tactilepipe.tool.model.variants import Architecture
from tactilepipe.tool.scenes import TOOL_SCENES, scene_label

REPO = Path(__file__).resolve().parents[2]


def study_arguments(description: str) -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--scene", default="tool_normal", choices=sorted(TOOL_SCENES))
    ap.add_argument("--scene-dir", type=Path, help="a built scene (default: the default build's, results/default/<scene>)")
    ap.add_argument("--variants", nargs="+", default=["no_ref"])
    return ap


@dataclass
class Scene:
    tool_train: dict        # params.yaml tool_train at default scale: the workflow's training settings
    variants: dict          # params.yaml tool_variants: each variant's architecture
    seed: int               # params.yaml seed: the workflow's split and model seed
    dir: Path
    label: str
    data: ToolFrames
    rmse_features: np.ndarray


def load_scene(args: argparse.Namespace) -> Scene:
    params = load_params(REPO / "params.yaml", {"scale": "default"})
    use_kernels(params["tool_train"]["kernels"])      # as the workflow's training stage, before torch loads
    scene_dir = args.scene_dir or REPO / "results" / "default" / args.scene
    label = scene_label(args.scene)
    data = ToolFrames(scene_dir / "data", label)
    return Scene(params["tool_train"], params["tool_variants"], params["seed"], scene_dir, label, data,
                 tactile_rmse_features(data.frames, data.references, data.trial_index))


def baseline_on(scene: Scene, split: dict) -> dict:
    """The tactile-RMSE linear baseline refitted on ``split``'s training rows, scored on its test rows."""
    test = np.asarray(split["test"])
    return summarise(scene.data.labels[test],
                     linear_fit_predictions(scene.data.labels, scene.rmse_features, split))


def train_on(scene_name: str, scene: Scene, split: dict, out: Path, variant: str, tool_train: dict) -> tuple[dict, float]:
    """Train one variant on ``split`` (written next to ``out``), as the workflow's training stage does;
    its eval.json fields and the wall time in seconds."""
    split_path = out.with_suffix(".split.json")
    split_path.write_text(json.dumps(split))
    out.mkdir()
    t0 = time.perf_counter()
    run = {"name": variant, "split": split["name"], "depth": tool_train["depth"], "image_size": tool_train["image_size"],
           "variant": {"name": variant, **Architecture.from_dict(scene.variants[variant]).as_dict()}}
    r = train_and_predict(scene_name, scene.dir / "data", split_path, out, run, tool_train, scene.seed, progress=False)
    return r, time.perf_counter() - t0
