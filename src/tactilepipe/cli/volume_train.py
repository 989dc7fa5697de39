"""Stage of the volume study: the MLP of one input modality, fitted on every fold."""

from __future__ import annotations

import json
from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.cli.volume_args import FOLDED, VOLUME_CHECKS
from tactilepipe.core.errors import TactilepipeError


@command("volume-train", "fit the MLP of one input modality on every fold",
         checks=VOLUME_CHECKS,
         params=("seed", "volume_sensor", "mlp.modalities", "mlp.hidden_units", "mlp.alpha", "mlp.batch_size",
                 "mlp.learning_rate", "mlp.tol", "mlp.n_iter_no_change", "mlp.max_iter", "mlp.restarts"),
         args=FOLDED + (arg("--modality", required=True), arg("--out-dir", required=True)))
def cmd_volume_train(args, p) -> None:
    import pandas as pd
    from tactilepipe.core.atomic import write_parquet, write_text
    from tactilepipe.volume.mlp import MLPConfig
    from tactilepipe.volume.train import fit_modality
    if args.modality not in p["mlp"]["modalities"]:
        raise TactilepipeError(f"unknown modality '{args.modality}' (params.yaml mlp.modalities: "
                               f"{sorted(p['mlp']['modalities'])})")
    data = pd.read_parquet(args.dataset)
    folds = json.loads(Path(args.folds).read_text())
    preds, summary = fit_modality(data, folds, p["mlp"]["modalities"][args.modality], p["volume_sensor"],
                                  MLPConfig.from_params(p["mlp"]), p["seed"])
    out = Path(args.out_dir)
    write_parquet(out / "predictions.parquet", preds)
    write_text(out / "folds.csv", summary.to_csv(index=False))
