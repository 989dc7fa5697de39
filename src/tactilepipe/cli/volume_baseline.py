"""Stage of the volume study: the algebraic friction baseline and its sweep of mu."""

from __future__ import annotations

import json
from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.cli.volume_args import FOLDED, VOLUME_CHECKS


@command("volume-baseline", "algebraic friction baseline with the mu sweep",
         checks=VOLUME_CHECKS,
         params=("volume_sensor", "baseline"),
         args=FOLDED + (arg("--predictions", required=True), arg("--fold-scores", required=True),
                        arg("--curve", required=True), arg("--mu", required=True)),
         rule={"scene": "volume", "inputs": {"dataset": "volume/dataset.parquet", "folds": "volume/folds.json"},
               "outputs": {"predictions": "volume/baseline/predictions.parquet", "fold-scores": "volume/baseline/folds.csv",
                           "curve": "volume/baseline/mu_curve.csv", "mu": "volume/baseline/mu.json"}})
def cmd_volume_baseline(args, p) -> None:
    import pandas as pd
    from tactilepipe.core.atomic import write_json, write_parquet, write_text
    from tactilepipe.volume.baseline import sweep
    data = pd.read_parquet(args.dataset)
    folds = json.loads(Path(args.folds).read_text())
    res = sweep(data, folds, p["volume_sensor"], p["baseline"])
    write_parquet(args.predictions, res["predictions"])
    write_text(args.fold_scores, res["summary"].to_csv(index=False))
    write_text(args.curve, res["curve"].to_csv(index=False))
    write_json(args.mu, {"mu_star": res["mu_star"], "optima": res["optima"].to_dict("records")})
