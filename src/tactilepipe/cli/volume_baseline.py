"""Stage of the volume study: the algebraic friction baseline and its sweep of mu."""

from __future__ import annotations

import json
from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.cli.volume_args import FOLDED, VOLUME_CHECKS


@command("volume-baseline", "algebraic friction baseline with the mu sweep",
         checks=VOLUME_CHECKS,
         params=("volume_sensor", "baseline"),
         args=FOLDED + (arg("--out-dir", required=True),))
def cmd_volume_baseline(args, p) -> None:
    import pandas as pd
    from tactilepipe.core.atomic import write_json, write_parquet, write_text
    from tactilepipe.volume.baseline import sweep
    data = pd.read_parquet(args.dataset)
    folds = json.loads(Path(args.folds).read_text())
    res = sweep(data, folds, p["volume_sensor"], p["baseline"])
    out = Path(args.out_dir)
    write_parquet(out / "predictions.parquet", res["predictions"])
    write_text(out / "folds.csv", res["summary"].to_csv(index=False))
    write_text(out / "mu_curve.csv", res["curve"].to_csv(index=False))
    write_json(out / "mu.json", {"mu_star": res["mu_star"], "optima": res["optima"].to_dict("records")})
