"""`tactilepipe <stage>`: every pipeline stage, usable with or without Snakemake.

Each stage reads params.yaml (plus `--override '{"scale": "smoke"}'`, which is how Snakemake
passes `--config` overrides on), and writes its outputs atomically. Imports are local to each
stage so a job only pays for what it uses.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from tactilepipe.errors import TactilepipeError


def _params(args, *keys: str) -> dict:
    """The stage's parameters: params.yaml (+ --override), resolved for the scale, cut down to
    ``keys`` (dotted, e.g. "tool_train.lr"). These keys are the stage's only way in: reading any
    other key raises, and the workflow reads the same keys (codedeps.stage_param_keys) to decide
    what a parameter change re-runs, so the two cannot drift apart."""
    from tactilepipe.config import declared, load_params
    from tactilepipe.errors import ConfigError
    try:
        overrides = json.loads(args.override) if args.override else {}
    except json.JSONDecodeError as exc:
        raise ConfigError(f"--override is not valid JSON: {exc}") from None
    if not isinstance(overrides, dict):
        raise ConfigError(f"--override must be a JSON object, got {type(overrides).__name__}")
    if args.scale:
        overrides["scale"] = args.scale
    return declared(load_params(args.params, overrides), keys, f"tactilepipe {args.command}")


def _write_provenance(args, out_dir: Path) -> None:
    """provenance.json beside a scene's metrics: the stages that made it (their code and the
    parameter values each declares), its input sessions, packages, machine and commit."""
    from tactilepipe.config import load_params
    from tactilepipe.provenance import write_provenance
    overrides = json.loads(args.override) if args.override else {}
    if args.scale:
        overrides["scale"] = args.scale
    write_provenance(out_dir / "provenance.json", args.provenance_stages, load_params(args.params, overrides),
                     args.sessions)


def _progress(iterable, desc: str, total: int | None = None):
    from tqdm import tqdm
    return tqdm(iterable, desc=desc, total=total, unit="bag", file=sys.stderr,
                disable=None, mininterval=1.0)


def _call(job):
    func, *args = job
    func(*args)


def _run_parallel(jobs: list, workers: int, desc: str) -> None:
    """Run (func, *args) jobs on ``workers`` processes, with a progress bar; errors propagate."""
    if workers <= 1:
        for job in _progress(jobs, desc):
            _call(job)
        return
    from concurrent.futures import ProcessPoolExecutor
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for _ in _progress(pool.map(_call, jobs), desc, total=len(jobs)):
            pass


# --- stages -----------------------------------------------------------------------------------

def cmd_simulate_volume(args) -> None:
    from tactilepipe.volume import simulate as sim
    p = _params(args, "seed", "simulate_volume")
    plan = sim.session_plan(p["simulate_volume"])
    chosen = [l for l in plan if not args.lifts or l.name in args.lifts]
    unknown = set(args.lifts or []) - {l.name for l in plan}
    if unknown:
        raise TactilepipeError(f"unknown lift names for this scale: {sorted(unknown)}")
    out = Path(args.out_dir)
    jobs = [(sim.write_lift_bag, out / f"{l.name}.bag", l, p["simulate_volume"], p["seed"]) for l in chosen]
    _run_parallel(jobs, args.jobs, "simulate volume")
    if args.labels:
        sim.write_session_labels(out, plan)


def cmd_simulate_tool(args) -> None:
    from tactilepipe.tool import simulate as tsim
    from tactilepipe.tool.digit_background import load_background
    p = _params(args, "seed", "simulate_tool")
    load_background(p["simulate_tool"]["render"]["background"])     # a bad frame stops here, before any trial
    out = Path(args.out_dir)
    chosen = [t for t in tsim.session_plan(p) if not args.lifts or t.name in args.lifts]
    tsim.write_session_calibration(out, p)
    _run_parallel([(tsim.write_trial, out, t, p) for t in chosen], args.jobs, "simulate tool")


def cmd_simulate_drift(args) -> None:
    from tactilepipe.drift import simulate as dsim
    p = _params(args, "seed", "simulate_drift", "simulate_volume")
    out = Path(args.out_dir)
    names = args.lifts or dsim.session_plan(p)
    _run_parallel([(dsim.write_drift_bag, out / f"{n}.bag", n, p) for n in names], args.jobs, "simulate drift")
    dsim.write_session_meta(out, p)


def cmd_simulate(args) -> None:
    {"volume": cmd_simulate_volume, "tool": cmd_simulate_tool, "drift": cmd_simulate_drift}[args.what](args)


def cmd_ingest(args) -> None:
    from tactilepipe.shards import ingest_bag
    if len(args.bags) % 2:
        raise TactilepipeError(f"ingest takes BAG SHARD pairs; got {len(args.bags)} paths "
                               f"(the last, {args.bags[-1]}, has no shard)")
    for bag, shard in zip(args.bags[0::2], args.bags[1::2]):
        info = ingest_bag(bag, shard)
        print(json.dumps(info))


def cmd_ingest_tool(args) -> None:
    from tactilepipe.tool.importers import open_trial
    from tactilepipe.tool.ingest import ingest_trial
    p = _params(args, "tool_ingest")
    ti = p["tool_ingest"]
    raw = open_trial(args.trial, args.format, ti["ros_topics"])
    info = ingest_trial(raw, args.out, ti["image_size"], ti)
    print(json.dumps({k: info[k] for k in ("trial", "frames", "force_samples", "clock", "drops")}))


def cmd_tool_clock_figure(args) -> None:
    from tactilepipe.tool.clock_report import clock_figure
    n = clock_figure([Path(s) for s in args.shards], Path(args.out))
    print(json.dumps({"figure": args.out, "trials_plotted": n}))


def cmd_realism(args) -> None:
    from tactilepipe.tool import realism
    result = realism.compare(args.real_dir, args.sim_dir, args.real_ref, args.sim_ref, args.max_frames)
    print(realism.report(result), end="")
    realism.figure(result, args.figure)
    print(f"figure: {args.figure}")


def cmd_tool_dataset(args) -> None:
    from tactilepipe.tool.dataset import build_tool_dataset
    p = _params(args, "tool_sync")
    build_tool_dataset([Path(s) for s in args.shards], args.kind, Path(args.out_dir), p["tool_sync"])


def cmd_tool_split(args) -> None:
    import pandas as pd
    from tactilepipe.atomic import write_json
    from tactilepipe.tool.splits import make_split
    p = _params(args, "seed", "tool_split.fractions", "tool_split.holdout_pose")
    sp = p["tool_split"]
    samples = pd.read_parquet(Path(args.data_dir) / "samples.parquet")
    split = make_split(samples, args.split, args.label, p["seed"], tuple(sp["fractions"]), sp["holdout_pose"])
    write_json(args.out, split)


def cmd_tool_train(args) -> None:
    from tactilepipe.tool.run_model import train_and_predict
    p = _params(args, "seed", "tool_train.lr", "tool_train.lr_schedule", "tool_train.batch_size",
                "tool_train.max_epochs", "tool_train.patience", "tool_train.max_train_batches_per_epoch",
                "tool_train.bn_recalibration_batches", "tool_train.device", "tool_train.amp", "tool_train.num_threads",
                "tool_train.gam_channel_gate")
    result = train_and_predict(args.scene, Path(args.data_dir), Path(args.split), Path(args.out_dir), args.variant,
                               args.depth, args.image_size, p["tool_train"], p["seed"], progress=not args.quiet)
    print(json.dumps({k: result[k] for k in ("variant", "depth", "image_size", "mae", "rmse", "r2", "train_s",
                                             "latency_ms")}))


def cmd_tool_report(args) -> None:
    from tactilepipe.tool.report_models import build_model_report
    p = _params(args, "tool_train.variants", "tool_train.split", "tool_train.depth", "tool_train.image_size",
                "tool_train.sweep")
    build_model_report(Path(args.in_dir), args.scene, p["tool_train"], args.runs)
    _write_provenance(args, Path(args.in_dir))


def cmd_predict(args) -> None:
    from tactilepipe.tool.predict import stream_predictions
    p = _params(args, "tool_ingest.ros_topics", "tool_ingest.image_size", "predict")
    stream_predictions(Path(args.checkpoint), Path(args.trial), args.format, p, limit=args.limit,
                       label_range=args.label_range)


def cmd_unpack_public(args) -> None:
    from tactilepipe.tool.public_archive import unpack, verify_listed, write_trials_template
    p = _params(args, "public_data.files", "public_data.session")
    verify_listed(args.archive, p["public_data"]["files"], args.name, "--name")
    session = Path(args.raw_root) / p["public_data"]["session"]
    trials = unpack(args.archive, args.name, session)
    added = write_trials_template(session)
    print(json.dumps({"archive": args.archive, "session": str(session), "trials": len(trials),
                      "trials_csv_rows_added": len(added)}))
    if added:
        print(f"{session / 'trials.csv'}: {len(added)} trials need a tool and pose (tool, orientation_deg, "
              f"insertion_mm) before the scene can be built", file=sys.stderr)


def cmd_tool_evaluate(args) -> None:
    from tactilepipe.tool.reproduce import evaluate_checkpoint
    p = _params(args, "tool_train.device", "public_data.files")
    if args.expect:
        from tactilepipe.tool.public_archive import verify_listed
        verify_listed(args.checkpoint, p["public_data"]["files"], args.expect, "--expect")
    if not (args.all_frames or args.split):
        raise TactilepipeError("tool-evaluate: give --split SPLIT_JSON (its test set) or --all-frames")
    split = None if args.all_frames else Path(args.split)
    result = evaluate_checkpoint(Path(args.checkpoint), Path(args.data_dir), args.scene, Path(args.out_dir), split,
                                 args.contaminated, p["tool_train"]["device"])
    print(json.dumps({k: result[k] for k in ("source", "frames", "n", "mae", "rmse", "r2", "contaminated")}))


def cmd_study000_table(args) -> None:
    from tactilepipe.tool.reproduce import protocol_table, published_table
    p = _params(args, "public_data.paper")
    paper, out = p["public_data"]["paper"], Path(args.out_dir)
    if args.published:
        published_table(Path(args.published), paper, out)
    else:
        protocol_table({Path(e).parent.name: Path(e) for e in args.evals}, paper, out)


def cmd_dataset(args) -> None:
    from tactilepipe.atomic import write_parquet, write_text
    from tactilepipe.volume.dataset import build_dataset, session_lifts
    p = _params(args, "volume_sessions", "segment", "papillarray_axes")
    lifts = session_lifts(p["volume_sessions"], Path(args.raw_root), Path(args.shard_root))
    data, qc = build_dataset(lifts, p["segment"], p["papillarray_axes"])
    write_parquet(args.out, data)
    write_text(args.qc, qc.to_csv(index=False))


def cmd_split(args) -> None:
    import pandas as pd
    from tactilepipe.atomic import write_json
    from tactilepipe.volume.folds import make_folds
    p = _params(args, "seed", "folds")
    lifts = pd.read_parquet(args.dataset, columns=["lift", "volume_ml", "set"]).drop_duplicates("lift")
    f = p["folds"]
    folds = make_folds(lifts, f["n_folds"], f["train_lifts_per_volume"], f["test_lifts_per_volume"],
                       p["seed"], source=args.dataset)
    write_json(args.out, folds)


def cmd_train(args) -> None:
    import pandas as pd
    from tactilepipe.atomic import write_parquet, write_text
    from tactilepipe.volume.mlp import MLPConfig
    from tactilepipe.volume.train import fit_modality
    p = _params(args, "seed", "volume_sensor", "mlp.modalities", "mlp.hidden_units", "mlp.alpha", "mlp.batch_size", "mlp.learning_rate",
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
    from tactilepipe.atomic import write_text
    from tactilepipe.volume.mlp import MLPConfig
    from tactilepipe.volume.train import grid_search
    p = _params(args, "seed", "volume_sensor", "mlp")
    grid = p["mlp"]["grid"]
    data = pd.read_parquet(args.dataset)
    folds = json.loads(Path(args.folds).read_text())
    table = grid_search(data, folds[0], p["mlp"]["modalities"][grid["modality"]], p["volume_sensor"],
                        MLPConfig.from_params(p["mlp"]), grid, p["seed"])
    write_text(args.out, table.to_csv(index=False))


def cmd_baseline(args) -> None:
    import pandas as pd
    from tactilepipe.atomic import write_json, write_parquet, write_text
    from tactilepipe.volume.baseline import sweep
    p = _params(args, "volume_sensor", "baseline")
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
    p = _params(args, "scale", "volume_sessions", "mlp.modalities", "mlp.grid.modality", "mlp.grid.inner_folds",
                "folds.train_lifts_per_volume", "folds.test_lifts_per_volume")
    build_report(Path(args.in_dir), p, Path(args.raw_root), Path(args.shard_root))
    _write_provenance(args, Path(args.in_dir))


def cmd_report_drift(args) -> None:
    from tactilepipe.drift.analyse import run
    p = _params(args, "drift")
    run([Path(s) for s in args.shards], Path(args.session_meta), Path(args.in_dir), p)
    _write_provenance(args, Path(args.in_dir))


def cmd_report_tool_data(args) -> None:
    from tactilepipe.tool.report_data import build_data_report
    p = _params(args, "tool_split.level_n")
    label = "normal" if args.what == "tool_normal" else "shear"
    build_data_report(Path(args.in_dir) / "data", Path(args.in_dir), label, p["tool_split"]["level_n"])
def cmd_volume_regimes(args) -> None:
    from tactilepipe.volume.regimes import compare_regimes
    p = _params(args, "scale", "seed", "simulate_volume", "segment", "papillarray_axes", "folds", "mlp", "baseline",
                "volume_sensor", "volume_regimes")
    metrics = compare_regimes(p, Path(args.out_dir), args.jobs, args.regimes)
    print(json.dumps({name: {"r2": {m: round(v["mean"], 4) for m, v in r["r2"].items()}, "mu_star": r["mu_star"]}
                      for name, r in metrics["regimes"].items()}))


def cmd_report(args) -> None:
    {"volume": cmd_report_volume, "drift": cmd_report_drift}.get(args.what, cmd_report_tool_data)(args)


# --- argument parsing -------------------------------------------------------------------------

def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tactilepipe", description=__doc__.splitlines()[0])
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--params", default="params.yaml", help="parameter file (default: params.yaml)")
    common.add_argument("--scale", help="smoke | default | paper (overrides params.yaml)")
    common.add_argument("--override", help="JSON object merged over params.yaml before validation")
    provenance = argparse.ArgumentParser(add_help=False)
    provenance.add_argument("--provenance-stages", nargs="*", default=[], metavar="STAGE",
                            help="CLI stages (cmd_*) whose code and parameters made this scene")
    provenance.add_argument("--sessions", nargs="*", default=[], help="the scene's input recording sessions")
    sub = parser.add_subparsers(dest="command", required=True, metavar="STAGE")

    s = sub.add_parser("simulate", parents=[common], help="write simulated raw recordings (ROS1 bags)")
    s.add_argument("what", choices=["volume", "drift", "tool"])
    s.add_argument("--out-dir", required=True, help="session folder, e.g. raw/volume/sim-default")
    s.add_argument("--lifts", nargs="*", help="only these recordings (default: the whole session)")
    s.add_argument("--labels", action="store_true", help="also write the session's lifts.csv")
    s.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    s.set_defaults(func=cmd_simulate)

    s = sub.add_parser("ingest", help="PapillArray bag(s) -> Parquet shard(s)")
    s.add_argument("bags", nargs="+", metavar="BAG SHARD", help="pairs: input bag, output shard")
    s.set_defaults(func=cmd_ingest)

    s = sub.add_parser("ingest-tool", parents=[common], help="tool trial (native, public or ROS) -> Parquet shard")
    s.add_argument("trial", help="trial folder or bag")
    s.add_argument("--format", choices=["native", "public", "ros"], required=True)
    s.add_argument("--out", required=True)
    s.set_defaults(func=cmd_ingest_tool)

    s = sub.add_parser("tool-clock-figure", help="QC figure: each native trial's clock correlation against lag")
    s.add_argument("--shards", nargs="+", required=True, help="a session's tool shards")
    s.add_argument("--out", required=True, help="PNG to write")
    s.set_defaults(func=cmd_tool_clock_figure)

    s = sub.add_parser("realism", help="compare two folders of tactile frames (real vs simulated): statistics and a figure")
    s.add_argument("real_dir", help="folder of real frames (JPEG/PNG, searched recursively; portrait or landscape)")
    s.add_argument("sim_dir", help="folder of simulated frames (e.g. raw/tool/sim-default)")
    s.add_argument("--real-ref", help="reference frame of the real folder (default: each sub-folder's first frame)")
    s.add_argument("--sim-ref", help="reference frame of the simulated folder (default: each sub-folder's first frame)")
    s.add_argument("--max-frames", type=int, default=2000, help="read at most this many frames per folder")
    s.add_argument("--figure", default="realism.png", help="figure to write (montage and histograms)")
    s.set_defaults(func=cmd_realism)

    s = sub.add_parser("tool-dataset", parents=[common], help="sync frames and force, references -> arrays")
    s.add_argument("--kind", choices=["normal", "shear"], required=True)
    s.add_argument("--shards", nargs="+", required=True)
    s.add_argument("--out-dir", required=True)
    s.set_defaults(func=cmd_tool_dataset)

    s = sub.add_parser("tool-split", parents=[common], help="train/validation/test split of a tool dataset")
    s.add_argument("--data-dir", required=True)
    s.add_argument("--split", required=True, help="frame | public_frame | trial | lopo, each with an optional _r<k> "
                                                  "(repeat k); or loto_<tool>")
    s.add_argument("--label", choices=["normal", "shear"], required=True)
    s.add_argument("--out", required=True)
    s.set_defaults(func=cmd_tool_split)

    s = sub.add_parser("tool-train", parents=[common], help="train one tool-force model variant, predict its test set")
    s.add_argument("--scene", choices=["tool_normal", "tool_shear"], required=True)
    s.add_argument("--variant", choices=["full", "no_ref", "single", "no_gam"], required=True)
    s.add_argument("--data-dir", required=True)
    s.add_argument("--split", required=True, help="split file (results/<scene>/splits/<name>.json)")
    s.add_argument("--out-dir", required=True)
    s.add_argument("--depth", type=int, choices=[18, 34, 50, 101], required=True, help="ResNet depth")
    s.add_argument("--image-size", type=int, required=True, help="train on frames downscaled to this size")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_tool_train)

    s = sub.add_parser("tool-report", parents=[common, provenance], help="metrics.json, tables and figures of the tool models")
    s.add_argument("--scene", choices=["tool_normal", "tool_shear"], required=True)
    s.add_argument("--in-dir", required=True)
    s.add_argument("--runs", nargs="+", required=True,
                   help="every run of the scene (results/<scene>/models/<run>; names as in tool/runs.py)")
    s.set_defaults(func=cmd_tool_report)

    s = sub.add_parser("predict", parents=[common], help="stream a recorded trial through a trained model")
    s.add_argument("--checkpoint", required=True, help="e.g. results/tool_normal/models/full/best.pt")
    s.add_argument("--trial", required=True, help="trial folder or bag")
    s.add_argument("--format", choices=["native", "public", "ros"], default="native")
    s.add_argument("--limit", type=int, help="stop after this many frame pairs")
    s.add_argument("--label-range", nargs=2, type=float, metavar=("MIN_N", "MAX_N"),
                   help="a public-code normal-force checkpoint: the force range (N) its outputs were scaled to "
                        "(the min and max over its training data set)")
    s.set_defaults(func=cmd_predict)

    s = sub.add_parser("unpack-public", parents=[common],
                       help="check a study-000 archive's size and sha256, unpack it into a public-layout session")
    s.add_argument("archive", help="e.g. raw/downloads/data_normal.zip")
    s.add_argument("--name", required=True, help="its entry in params.yaml public_data.files (data_normal, data_shear)")
    s.add_argument("--raw-root", default="raw/tool", help="the session folder public_data.session is made here")
    s.set_defaults(func=cmd_unpack_public)

    s = sub.add_parser("tool-evaluate", parents=[common],
                       help="evaluate a checkpoint (ours or the public code's) on a tool dataset")
    s.add_argument("--checkpoint", required=True, help="best.pt, or a public best_model_*.pth")
    s.add_argument("--expect", metavar="NAME", help="first check the checkpoint's size and sha256 against "
                                                   "params.yaml public_data.files.NAME")
    s.add_argument("--scene", choices=["tool_normal", "tool_shear"], required=True)
    s.add_argument("--data-dir", required=True)
    s.add_argument("--split", help="split file: evaluate its test set")
    s.add_argument("--all-frames", action="store_true", help="evaluate every frame of the data set")
    s.add_argument("--contaminated", action="store_true",
                   help="label the result contaminated (the weights were trained on these frames)")
    s.add_argument("--out-dir", required=True)
    s.set_defaults(func=cmd_tool_evaluate)

    s = sub.add_parser("study000-table", parents=[common], help="study 000's protocols (or published weights) beside the paper")
    s.add_argument("--evals", nargs="*", default=[], help="eval.json of the runs full_public_frame, full_trial")
    s.add_argument("--published", help="eval.json of the published weights over every frame")
    s.add_argument("--out-dir", required=True)
    s.set_defaults(func=cmd_study000_table)

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

    s = sub.add_parser("train", parents=[common], help="fit the MLP of one input modality on every fold")
    s.add_argument("--modality", required=True)
    s.add_argument("--dataset", required=True)
    s.add_argument("--folds", required=True)
    s.add_argument("--out-dir", required=True)
    s.set_defaults(func=cmd_train)

    s = sub.add_parser("gridsearch", parents=[common], help="MLP grid search on the first fold")
    s.add_argument("--dataset", required=True)
    s.add_argument("--folds", required=True)
    s.add_argument("--out", required=True)
    s.set_defaults(func=cmd_gridsearch)

    s = sub.add_parser("baseline", parents=[common], help="algebraic friction baseline with the mu sweep")
    s.add_argument("--dataset", required=True)
    s.add_argument("--folds", required=True)
    s.add_argument("--out-dir", required=True)
    s.set_defaults(func=cmd_baseline)

    s = sub.add_parser("volume-regimes", parents=[common],
                       help="Table 1 of the volume study under each grasp regime (params.yaml volume_regimes)")
    s.add_argument("--out-dir", required=True, help="e.g. results/volume_regimes")
    s.add_argument("--regimes", nargs="*", help="only these regimes (default: all of volume_regimes)")
    s.add_argument("--jobs", type=int, default=1, help="worker processes for the simulation (default 1)")
    s.set_defaults(func=cmd_volume_regimes)

    s = sub.add_parser("report", parents=[common, provenance], help="metrics.json, tables and figures of a scene")
    s.add_argument("what", choices=["volume", "drift", "tool_normal", "tool_shear"])
    s.add_argument("--in-dir", required=True, help="the scene's results folder")
    s.add_argument("--raw-root", default="raw/volume")
    s.add_argument("--shard-root", default="results/volume/shards")
    s.add_argument("--shards", nargs="*", default=[], help="drift: the recordings' shards")
    s.add_argument("--session-meta", help="drift: the session's session.json (reference weight)")
    s.set_defaults(func=cmd_report)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        args.func(args)
    except TactilepipeError as exc:
        print(f"tactilepipe {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        # the machine, not the data: a full disk, a read-only or forbidden folder, a size limit,
        # a file that vanished. One line naming the file, no traceback.
        print(f"tactilepipe {args.command}: error: {_os_error_line(exc)}", file=sys.stderr)
        return 1
    return 0


def _os_error_line(exc: OSError) -> str:
    """'<path>: <problem>' of an OSError (pyarrow and numpy often leave filename unset)."""
    import os
    problem = exc.strerror or (os.strerror(exc.errno) if exc.errno else str(exc) or type(exc).__name__)
    if exc.filename is None:
        return f"{problem} ({str(exc).strip() or type(exc).__name__})" if str(exc) != problem else problem
    where = f"{exc.filename} -> {exc.filename2}" if exc.filename2 else str(exc.filename)
    return f"{where}: {problem}"
