"""What the tool-scene studies (study_grasps.py, study_splits.py) share: their common arguments and
loading a built scene with its tactile-RMSE features (computed once, refitted per arm)."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tactilepipe.config import load_params
from tactilepipe.tool.evaluate import tactile_rmse_features
from tactilepipe.tool.loader import ToolFrames
from tactilepipe.tool.run_model import LABELS

REPO = Path(__file__).resolve().parents[1]


def study_arguments(description: str) -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--scene", default="tool_normal", choices=sorted(LABELS))
    ap.add_argument("--scene-dir", type=Path, help="a built scene (default: results/<scene>)")
    ap.add_argument("--variants", nargs="+", default=["no_ref"])
    return ap


@dataclass
class Scene:
    tool_train: dict        # params.yaml tool_train at default scale: the workflow's training settings
    seed: int               # params.yaml seed: the workflow's split and model seed
    dir: Path
    label: str
    data: ToolFrames
    rmse_features: np.ndarray


def load_scene(args: argparse.Namespace) -> Scene:
    params = load_params(REPO / "params.yaml", {"scale": "default"})
    scene_dir = args.scene_dir or REPO / "results" / args.scene
    label, _ = LABELS[args.scene]
    data = ToolFrames(scene_dir / "data", label)
    return Scene(params["tool_train"], params["seed"], scene_dir, label, data,
                 tactile_rmse_features(data.frames, data.references, data.trial_index))
