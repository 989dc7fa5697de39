"""How the error on unseen grasps depends on how many grasps a model trained on (a learning curve).

The question behind it: without its reference frame, does a variant lose to the
tactile-RMSE baseline because it saw too few grasps, or because a single frame cannot separate a
re-grasp from a press? Each arm trains one variant on the workflow's trial split of a built scene
(same validation and test trials, same label scaling, same training settings as the workflow),
but on a subset of the training data:
- ``trials=f``: a fraction f of the training trials (nested subsets, stratified by tool), every frame;
- ``stride=k``: every training trial, every k-th frame (the same number of frames as f = 1/k, but
  from all the grasps).
Every arm gets the same number of optimiser steps as the whole training set (max_epochs and
patience scaled up by the inverse of the kept share): a smaller set trained for fewer steps would
mix "fewer grasps" with "shorter training". The tactile-RMSE baseline is refitted on the same
training subset, so every row compares like with like. One run prints the whole table.

Needs a built scene (``snakemake --cores 2 results/default/tool_normal/splits/trial.json``). Usage:
    python studies/tool_models/study_grasps.py [--scene tool_normal] [--scene-dir results/default/tool_normal]
                                      [--variants no_ref full] [--fractions 0.5 1] [--strides 2]
About 10 minutes on 2 cores at default scale with the default arguments.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from study_common import baseline_on, load_scene, study_arguments, train_on
from tactilepipe.tool.data.splits import thin_training


def main() -> None:
    ap = study_arguments(__doc__.splitlines()[0])
    ap.add_argument("--fractions", nargs="*", type=float, default=[0.5, 1.0])
    ap.add_argument("--strides", nargs="*", type=int, default=[2])
    ap.add_argument("--same-epochs", action="store_true",
                    help="train every arm for the workflow's max_epochs (fewer steps on a smaller set)")
    args = ap.parse_args()

    scene = load_scene(args)
    tp, seed, data = scene.tool_train, scene.seed, scene.data
    split = json.loads((scene.dir / "splits" / f"{tp['split']}.json").read_text())
    test = np.asarray(split["test"])

    arms = [(f"trials={f:g}", thin_training(split, data.samples, seed, trial_fraction=f)) for f in args.fractions]
    arms += [(f"stride={k}", thin_training(split, data.samples, seed, frame_stride=k)) for k in args.strides]

    rows = []
    with tempfile.TemporaryDirectory(prefix="tactilepipe-study-grasps-") as tmp:
        for arm, sub in arms:
            idx = np.asarray(sub["train"])
            n_trials = len(sub["trials"]["train"])
            b = baseline_on(scene, sub)
            rows.append({"arm": arm, "model": "tactile_rmse_linear", "train_trials": n_trials,
                         "train_pairs": len(idx), "mae": b["mae"], "r2": b["r2"]})
            stretch = 1.0 if args.same_epochs else len(split["train"]) / len(idx)   # same optimiser steps
            tp_arm = {**tp, "max_epochs": round(tp["max_epochs"] * stretch), "patience": round(tp["patience"] * stretch)}
            for variant in args.variants:
                r, seconds = train_on(args.scene, scene, sub, Path(tmp) / f"{arm}-{variant}", variant, tp_arm)
                rows.append({"arm": arm, "model": variant, "train_trials": n_trials, "train_pairs": len(idx),
                             "mae": r["mae"], "r2": r["r2"], "epochs": r["epochs"], "best_epoch": r["best_epoch"],
                             "train_s": seconds})
                print(f"{arm:<12}{variant:<22}{n_trials:>6} trials {len(idx):>6} pairs   "
                      f"MAE {r['mae']:.3f} N  R2 {r['r2']:.3f}  ({rows[-1]['train_s']:.0f} s)", flush=True)

    table = pd.DataFrame(rows)
    print(f"\n== {args.scene}: test set of the '{split['name']}' split "
          f"({len(test)} pairs, {len(split['trials']['test'])} trials), "
          f"depth {tp['depth']}, {tp['image_size']} px, up to {tp['max_epochs']} epochs of the whole set")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))


if __name__ == "__main__":
    main()
