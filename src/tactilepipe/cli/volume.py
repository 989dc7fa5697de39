"""Stages of the container-volume study: simulate lifts, ingest bags, segment, fold, train the MLPs,
the friction baseline, the report, and the grasp-regime comparison."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from tactilepipe.cli.common import stage_params, run_parallel
from tactilepipe.core.errors import TactilepipeError


def cmd_simulate_volume(args) -> None:
    from tactilepipe.volume import simulate as sim
    p = stage_params(args, "seed", "simulate_volume")
    plan = sim.session_plan(p["simulate_volume"])
    chosen = [l for l in plan if not args.lifts or l.name in args.lifts]
    unknown = set(args.lifts or []) - {l.name for l in plan}
    if unknown:
        raise TactilepipeError(f"unknown lift names for this scale: {sorted(unknown)}")
    out = Path(args.out_dir)
    jobs = [(sim.write_lift_bag, out / f"{l.name}.bag", l, p["simulate_volume"], p["seed"]) for l in chosen]
    run_parallel(jobs, args.jobs, "simulate volume")
    if args.labels:
        sim.write_session_labels(out, plan)


def cmd_ingest(args) -> None:
    from tactilepipe.papillarray.shards import ingest_bag
    if len(args.bags) % 2:
        raise TactilepipeError(f"ingest takes BAG SHARD pairs; got {len(args.bags)} paths "
                               f"(the last, {args.bags[-1]}, has no shard)")
    for bag, shard in zip(args.bags[0::2], args.bags[1::2]):
        info = ingest_bag(bag, shard)
        print(json.dumps(info))


def cmd_dataset(args) -> None:
    from tactilepipe.core.atomic import write_parquet, write_text
    from tactilepipe.volume.dataset import build_dataset, session_lifts
    p = stage_params(args, "volume_sessions", "segment", "papillarray_axes")
    lifts = session_lifts(p["volume_sessions"], Path(args.raw_root), Path(args.shard_root))
    data, qc = build_dataset(lifts, p["segment"], p["papillarray_axes"])
    write_parquet(args.out, data)
    write_text(args.qc, qc.to_csv(index=False))


def cmd_split(args) -> None:
    import pandas as pd
    from tactilepipe.core.atomic import write_json
    from tactilepipe.volume.folds import make_folds
    p = stage_params(args, "seed", "folds")
    lifts = pd.read_parquet(args.dataset, columns=["lift", "volume_ml", "set"]).drop_duplicates("lift")
    f = p["folds"]
    folds = make_folds(lifts, f["n_folds"], f["train_lifts_per_volume"], f["test_lifts_per_volume"],
                       p["seed"], source=args.dataset)
    write_json(args.out, folds)


def cmd_train(args) -> None:
    import pandas as pd
    from tactilepipe.core.atomic import write_parquet, write_text
    from tactilepipe.volume.mlp import MLPConfig
    from tactilepipe.volume.train import fit_modality
    p = stage_params(args, "seed", "volume_sensor", "mlp.modalities", "mlp.hidden_units", "mlp.alpha", "mlp.batch_size", "mlp.learning_rate",
                "mlp.tol", "mlp.n_iter_no_change", "mlp.max_iter", "mlp.restarts")
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


def cmd_gridsearch(args) -> None:
    import pandas as pd
    from tactilepipe.core.atomic import write_text
    from tactilepipe.volume.mlp import MLPConfig
    from tactilepipe.volume.train import grid_search
    p = stage_params(args, "seed", "volume_sensor", "mlp")
    grid = p["mlp"]["grid"]
    data = pd.read_parquet(args.dataset)
    folds = json.loads(Path(args.folds).read_text())
    table = grid_search(data, folds[0], p["mlp"]["modalities"][grid["modality"]], p["volume_sensor"],
                        MLPConfig.from_params(p["mlp"]), grid, p["seed"])
    write_text(args.out, table.to_csv(index=False))


def cmd_baseline(args) -> None:
    import pandas as pd
    from tactilepipe.core.atomic import write_json, write_parquet, write_text
    from tactilepipe.volume.baseline import sweep
    p = stage_params(args, "volume_sensor", "baseline")
    data = pd.read_parquet(args.dataset)
    folds = json.loads(Path(args.folds).read_text())
    res = sweep(data, folds, p["volume_sensor"], p["baseline"])
    out = Path(args.out_dir)
    write_parquet(out / "predictions.parquet", res["predictions"])
    write_text(out / "folds.csv", res["summary"].to_csv(index=False))
    write_text(out / "mu_curve.csv", res["curve"].to_csv(index=False))
    write_json(out / "mu.json", {"mu_star": res["mu_star"], "optima": res["optima"].to_dict("records")})


def cmd_report_volume(args) -> None:
    from tactilepipe.volume.report import build_report
    p = stage_params(args, "scale", "volume_sessions", "mlp.modalities", "mlp.grid.modality", "mlp.grid.inner_folds",
                "folds.train_lifts_per_volume", "folds.test_lifts_per_volume")
    build_report(Path(args.in_dir), p, Path(args.raw_root), Path(args.shard_root))
    from tactilepipe.cli.provenance import write_scene_provenance
    write_scene_provenance(args, Path(args.in_dir))


def cmd_volume_regimes(args) -> None:
    from tactilepipe.volume.regimes import compare_regimes
    p = stage_params(args, "scale", "seed", "simulate_volume", "segment", "papillarray_axes", "folds", "mlp", "baseline",
                "volume_sensor", "volume_regimes")
    metrics = compare_regimes(p, Path(args.out_dir), args.jobs, args.regimes)
    print(json.dumps({name: {"r2": {m: round(v["mean"], 4) for m, v in r["r2"].items()}, "mu_star": r["mu_star"]}
                      for name, r in metrics["regimes"].items()}))


def add_parsers(sub, common, provenance) -> None:
    """This study's sub-commands, on the parser's ``sub``; ``common`` and ``provenance`` are the
    shared option groups."""
    s = sub.add_parser("ingest", help="PapillArray bag(s) -> Parquet shard(s)")
    s.add_argument("bags", nargs="+", metavar="BAG SHARD", help="pairs: input bag, output shard")
    s.set_defaults(func=cmd_ingest)

    s = sub.add_parser("dataset", parents=[common], help="segment the off-table phase of every lift")
    s.add_argument("--raw-root", default="raw/volume")
    s.add_argument("--shard-root", default="results/volume/shards")
    s.add_argument("--out", required=True)
    s.add_argument("--qc", required=True)
    s.set_defaults(func=cmd_dataset)

    s = sub.add_parser("split", parents=[common], help="seeded train/test lift draws stratified by volume")
    s.add_argument("--dataset", required=True)
    s.add_argument("--out", required=True)
    s.set_defaults(func=cmd_split)

    # the data set and its folds: what the model stages read
    folded = argparse.ArgumentParser(add_help=False)
    folded.add_argument("--dataset", required=True)
    folded.add_argument("--folds", required=True)

    s = sub.add_parser("train", parents=[common, folded], help="fit the MLP of one input modality on every fold")
    s.add_argument("--modality", required=True)
    s.add_argument("--out-dir", required=True)
    s.set_defaults(func=cmd_train)

    s = sub.add_parser("gridsearch", parents=[common, folded], help="MLP grid search on the first fold")
    s.add_argument("--out", required=True)
    s.set_defaults(func=cmd_gridsearch)

    s = sub.add_parser("baseline", parents=[common, folded], help="algebraic friction baseline with the mu sweep")
    s.add_argument("--out-dir", required=True)
    s.set_defaults(func=cmd_baseline)

    s = sub.add_parser("volume-regimes", parents=[common],
                       help="Table 1 of the volume study under each grasp regime (params.yaml volume_regimes)")
    s.add_argument("--out-dir", required=True, help="e.g. results/volume_regimes")
    s.add_argument("--regimes", nargs="*", help="only these regimes (default: all of volume_regimes)")
    s.add_argument("--jobs", type=int, default=1, help="worker processes for the simulation (default 1)")
    s.set_defaults(func=cmd_volume_regimes)
