"""Stages of the container-volume study: simulate lifts, ingest bags, segment, fold, train the MLPs,
the friction baseline, the report, and the grasp-regime comparison."""

from __future__ import annotations

import json
from pathlib import Path

from tactilepipe.cli.common import run_parallel
from tactilepipe.cli.registry import arg, command
from tactilepipe.core.errors import TactilepipeError
from tactilepipe.papillarray import checks as papillarray_checks
from tactilepipe.volume import checks as volume_checks

# the cross-key checks a stage runs on params.yaml by hand: the study's own and its sensor's
# (the workflow runs every study's: pipeline/studies.py)
VOLUME_CHECKS = (volume_checks.check, papillarray_checks.check)
PAPILLARRAY_CHECKS = (papillarray_checks.check,)

# the data set and its folds: what the model stages read
FOLDED = (arg("--dataset", required=True), arg("--folds", required=True))


@command("volume-simulate", "write simulated PapillArray lifts (ROS1 bags) of the volume study",
         checks=VOLUME_CHECKS,
         params=("seed", "simulate_volume"),
         args=(arg("--out-dir", required=True, help="session folder, e.g. raw/volume/sim-default"),
               arg("--lifts", nargs="*", help="only these lifts (default: the whole session)"),
               arg("--labels", action="store_true", help="also write the session's lifts.csv"),
               arg("--jobs", type=int, default=1, help="worker processes (default 1)")))
def cmd_volume_simulate(args, p) -> None:
    from tactilepipe.volume import simulate as sim
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


@command("papillarray-ingest", "PapillArray bag(s) -> Parquet shard(s) (the volume and drift studies)",
         checks=PAPILLARRAY_CHECKS,
         params=("papillarray_ingest",),
         args=(arg("bags", nargs="+", metavar="BAG SHARD", help="pairs: input bag, output shard"),))
def cmd_papillarray_ingest(args, p) -> None:
    from tactilepipe.papillarray.shards import ingest_bag
    if len(args.bags) % 2:
        raise TactilepipeError(f"papillarray-ingest takes BAG SHARD pairs; got {len(args.bags)} paths "
                               f"(the last, {args.bags[-1]}, has no shard)")
    for bag, shard in zip(args.bags[0::2], args.bags[1::2]):
        info = ingest_bag(bag, shard, max_span_offset_s=p["papillarray_ingest"]["max_span_offset_s"])
        print(json.dumps(info))


@command("volume-dataset", "segment the off-table phase of every lift",
         checks=VOLUME_CHECKS,
         params=("volume_sessions", "segment", "papillarray_axes", "volume_checks"),
         args=(arg("--raw-root", default="raw/volume"), arg("--shard-root", default="results/default/volume/shards"),
               arg("--out", required=True), arg("--qc", required=True)))
def cmd_volume_dataset(args, p) -> None:
    from tactilepipe.core.atomic import write_parquet, write_text
    from tactilepipe.volume.dataset import build_dataset, session_lifts
    lifts = session_lifts(p["volume_sessions"], Path(args.raw_root), Path(args.shard_root))
    data, qc = build_dataset(lifts, p["segment"], p["papillarray_axes"], p["volume_checks"])
    write_parquet(args.out, data)
    write_text(args.qc, qc.to_csv(index=False))


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


@command("volume-report", "metrics.json, tables and figures of the volume study",
         checks=VOLUME_CHECKS,
         params=("scale", "volume_sessions", "mlp.modalities", "mlp.grid.modality", "mlp.grid.inner_folds",
                 "folds.train_lifts_per_volume", "folds.test_lifts_per_volume"),
         args=(arg("--in-dir", required=True, help="the scene's results folder"),
               arg("--raw-root", default="raw/volume"), arg("--shard-root", default="results/default/volume/shards")),
         provenance=True)
def cmd_volume_report(args, p) -> None:
    from tactilepipe.volume.report import build_report
    build_report(Path(args.in_dir), p, Path(args.raw_root), Path(args.shard_root))
    from tactilepipe.cli.provenance import write_scene_provenance
    write_scene_provenance(args, Path(args.in_dir))


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
