"""How much a variant's test error, and its margin over the tactile-RMSE baseline, move with the trial split.

The question behind it: with 8-29 test grasps per scene, is "variant X loses to the
baseline" a property of the variant or of which grasps landed in the test set? Each arm draws the
trial-grouped split (the workflow's ``trial`` split, stratified by tool) with another split seed,
refits the tactile-RMSE baseline on its training trials, and trains the chosen variants with the
workflow's settings and model seed. The first split seed defaults to params.yaml ``seed``, so the
first row reproduces the workflow's numbers. One run prints every row, then mean ± std over the
splits of MAE, R² and the margin to the baseline (paired: same test trials), and on how many splits
the variant beats the baseline on both MAE and R².

Needs a built scene's data (``snakemake --cores 2 results/default/tool_normal/data/samples.parquet``). Usage:
    python studies/tool_models/study_splits.py [--scene tool_normal] [--variants no_ref] [--splits 5]
About 2.5 minutes per variant and split on 2 cores at default scale (no_ref, Fz).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import pandas as pd

from study_common import baseline_on, load_scene, study_arguments, train_on
from tactilepipe.tool.data.splits import make_split


def main() -> None:
    ap = study_arguments(__doc__.splitlines()[0])
    ap.add_argument("--splits", type=int, default=5, help="how many split seeds (seed, seed+1, ...)")
    ap.add_argument("--first-split-seed", type=int, help="default: params.yaml seed (the workflow's split)")
    args = ap.parse_args()

    scene = load_scene(args)
    tp, seed, label, data = scene.tool_train, scene.seed, scene.label, scene.data
    first = seed if args.first_split_seed is None else args.first_split_seed

    rows = []
    with tempfile.TemporaryDirectory(prefix="tactilepipe-study-splits-") as tmp:
        for split_seed in range(first, first + args.splits):
            split = make_split(data.samples, "trial", label, split_seed)
            n_test = len(split["trials"]["test"])
            base = baseline_on(scene, split)
            rows.append({"split_seed": split_seed, "model": "tactile_rmse_linear", "test_trials": n_test,
                         "mae": base["mae"], "r2": base["r2"]})
            print(f"split {split_seed}  {'tactile_rmse_linear':<20}{n_test:>4} test trials   "
                  f"MAE {base['mae']:.3f} N  R2 {base['r2']:.3f}", flush=True)
            for variant in args.variants:
                r, seconds = train_on(args.scene, scene, split, Path(tmp) / f"{split_seed}-{variant}", variant, tp)
                rows.append({"split_seed": split_seed, "model": variant, "test_trials": n_test,
                             "mae": r["mae"], "r2": r["r2"], "d_mae": r["mae"] - base["mae"],
                             "d_r2": r["r2"] - base["r2"],
                             "beats": bool(r["mae"] < base["mae"] and r["r2"] > base["r2"]),
                             "epochs": r["epochs"], "best_epoch": r["best_epoch"], "train_s": seconds})
                print(f"split {split_seed}  {variant:<20}{n_test:>4} test trials   MAE {r['mae']:.3f} N  "
                      f"R2 {r['r2']:.3f}  vs baseline {rows[-1]['d_mae']:+.3f} N / {rows[-1]['d_r2']:+.3f}  "
                      f"({rows[-1]['train_s']:.0f} s)", flush=True)

    table = pd.DataFrame(rows)
    print(f"\n== {args.scene}: '{tp['split']}'-style trial splits, seeds {first}..{first + args.splits - 1}; "
          f"depth {tp['depth']}, {tp['image_size']} px, model seed {seed}")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    summary = table.groupby("model", sort=False).agg(
        mae_mean=("mae", "mean"), mae_std=("mae", "std"), r2_mean=("r2", "mean"), r2_std=("r2", "std"),
        **({"d_mae_mean": ("d_mae", "mean"), "d_mae_std": ("d_mae", "std"), "d_r2_mean": ("d_r2", "mean"),
            "d_r2_std": ("d_r2", "std"), "beats": ("beats", "sum")} if "beats" in table else {}))
    if "beats" in summary:
        summary["beats"] = [f"{int(n)}/{args.splits}" if m != "tactile_rmse_linear" else "-"
                            for m, n in summary["beats"].items()]
    print(f"\n== mean ± std over {args.splits} splits (d_* = variant - baseline on the same split; "
          f"beats = splits where MAE is lower and R2 higher)")
    print(summary.to_string(float_format=lambda v: f"{v:.3f}"))


if __name__ == "__main__":
    main()
