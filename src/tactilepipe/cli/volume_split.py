"""Stage of the volume study: the seeded train and test lifts of each fold."""

from __future__ import annotations

from tactilepipe.cli.registry import arg, command
from tactilepipe.cli.volume_args import VOLUME_CHECKS


@command("volume-split", "seeded train/test lift draws stratified by volume",
         checks=VOLUME_CHECKS,
         params=("seed", "folds"),
         args=(arg("--dataset", required=True), arg("--out", required=True)),
         # a second's work on the dataset table: on a cluster it runs where Snakemake runs
         rule={"scene": "volume", "inputs": {"dataset": "volume/dataset.parquet"},
               "outputs": {"out": "volume/folds.json"}, "local": True})
def cmd_volume_split(args, p) -> None:
    import pandas as pd
    from tactilepipe.core.atomic import write_json
    from tactilepipe.volume.folds import make_folds
    lifts = pd.read_parquet(args.dataset, columns=["lift", "volume_ml", "set"]).drop_duplicates("lift")
    f = p["folds"]
    folds = make_folds(lifts, f["n_folds"], f["train_lifts_per_volume"], f["test_lifts_per_volume"],
                       p["seed"], source=args.dataset)
    write_json(args.out, folds)
