"""Stage of the volume study: the MLP's grid search on the first fold."""

from __future__ import annotations

import json
from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.cli.volume_args import FOLDED, VOLUME_CHECKS


@command("volume-gridsearch", "MLP grid search on the first fold",
         checks=VOLUME_CHECKS,
         params=("seed", "volume_sensor", "mlp"),
         args=FOLDED + (arg("--out", required=True),),
         rule={"scene": "volume", "inputs": {"dataset": "volume/dataset.parquet", "folds": "volume/folds.json"},
               "outputs": {"out": "volume/mlp/grid.csv"}})
def cmd_volume_gridsearch(args, p) -> None:
    import pandas as pd
    from tactilepipe.core.atomic import write_text
    from tactilepipe.volume.mlp import MLPConfig
    from tactilepipe.volume.train import grid_search
    grid = p["mlp"]["grid"]
    data = pd.read_parquet(args.dataset)
    folds = json.loads(Path(args.folds).read_text())
    table = grid_search(data, folds[0], p["mlp"]["modalities"][grid["modality"]], p["volume_sensor"],
                        MLPConfig.from_params(p["mlp"]), grid, p["seed"])
    write_text(args.out, table.to_csv(index=False))
