"""Command of the volume study: Table 1 under each grasp regime."""

from __future__ import annotations

import json
from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.cli.volume_args import VOLUME_CHECKS


@command("volume-regimes", "Table 1 of the volume study under each grasp regime (params.yaml volume_regimes)",
         checks=VOLUME_CHECKS,
         params=("scale", "seed", "simulate_volume", "segment", "papillarray_axes", "volume_checks",
                 "folds", "mlp", "baseline", "volume_sensor", "volume_regimes"),
         args=(arg("--out-dir", required=True, help="e.g. results/default/volume_regimes"),
               arg("--regimes", nargs="*", help="only these regimes (default: all of volume_regimes)"),
               arg("--jobs", type=int, default=1, help="worker processes for the simulation (default 1)")))
def cmd_volume_regimes(args, p) -> None:
    from tactilepipe.volume.regimes import compare_regimes
    metrics = compare_regimes(p, Path(args.out_dir), args.jobs, args.regimes)
    print(json.dumps({name: {"r2": {m: round(v["mean"], 4) for m, v in r["r2"].items()}, "mu_star": r["mu_star"]}
                      for name, r in metrics["regimes"].items()}))
