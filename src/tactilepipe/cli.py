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


def _params(args) -> dict:
    from tactilepipe.config import load_params
    from tactilepipe.errors import ConfigError
    try:
        overrides = json.loads(args.override) if args.override else {}
    except json.JSONDecodeError as exc:
        raise ConfigError(f"--override is not valid JSON: {exc}") from None
    if not isinstance(overrides, dict):
        raise ConfigError(f"--override must be a JSON object, got {type(overrides).__name__}")
    if args.scale:
        overrides["scale"] = args.scale
    return load_params(args.params, overrides)


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

def cmd_simulate(args) -> None:
    p = _params(args)
    out = Path(args.out_dir)
    if args.what == "volume":
        from tactilepipe.volume import simulate as sim
        plan = sim.session_plan(p["simulate_volume"])
        chosen = [l for l in plan if not args.lifts or l.name in args.lifts]
        unknown = set(args.lifts or []) - {l.name for l in plan}
        if unknown:
            raise TactilepipeError(f"unknown lift names for this scale: {sorted(unknown)}")
        jobs = [(sim.write_lift_bag, out / f"{l.name}.bag", l, p["simulate_volume"], p["seed"]) for l in chosen]
        _run_parallel(jobs, args.jobs, "simulate volume")
        if args.labels:
            sim.write_session_labels(out, plan)
    elif args.what == "tool":
        from tactilepipe.tool import simulate as tsim
        plan = tsim.session_plan(p)
        chosen = [t for t in plan if not args.lifts or t.name in args.lifts]
        tsim.write_session_calibration(out, p)
        _run_parallel([(tsim.write_trial, out, t, p) for t in chosen], args.jobs, "simulate tool")
    else:
        from tactilepipe.drift import simulate as dsim
        names = args.lifts or dsim.session_plan(p)
        _run_parallel([(dsim.write_drift_bag, out / f"{n}.bag", n, p) for n in names], args.jobs, "simulate drift")


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
    p = _params(args)
    ti = p["tool_ingest"]
    raw = open_trial(args.trial, args.format, ti["ros_topics"])
    info = ingest_trial(raw, args.out, ti["image_size"], ti)
    print(json.dumps({k: info[k] for k in ("trial", "frames", "force_samples", "clock", "drops")}))


def cmd_tool_clock_figure(args) -> None:
    from tactilepipe.tool.clock_report import clock_figure
    n = clock_figure([Path(s) for s in args.shards], Path(args.out))
    print(json.dumps({"figure": args.out, "trials_plotted": n}))


def cmd_tool_dataset(args) -> None:
    from tactilepipe.tool.dataset import build_tool_dataset
    p = _params(args)
    build_tool_dataset([Path(s) for s in args.shards], args.kind, Path(args.out_dir), p["tool_sync"])


def cmd_tool_split(args) -> None:
    import pandas as pd
    from tactilepipe.atomic import write_json
    from tactilepipe.tool.splits import make_split
    p = _params(args)
    sp = p["tool_split"]
    samples = pd.read_parquet(Path(args.data_dir) / "samples.parquet")
    split = make_split(samples, args.split, args.label, p["seed"], tuple(sp["fractions"]),
                       sp["holdout_tool"], sp["holdout_pose"])
    write_json(args.out, split)


def cmd_tool_train(args) -> None:
    from tactilepipe.tool.run_model import train_and_predict
    p = _params(args)
    tp = p["tool_train"]
    result = train_and_predict(args.scene, Path(args.data_dir), Path(args.split), Path(args.out_dir), args.variant,
                               args.depth or tp["depth"], args.image_size or p["tool_ingest"]["image_size"],
                               tp, p["seed"], progress=not args.quiet)
    print(json.dumps({k: result[k] for k in ("variant", "depth", "image_size", "mae", "rmse", "r2", "train_s",
                                             "latency_ms")}))


def cmd_tool_report(args) -> None:
    from tactilepipe.tool.report_models import build_model_report
    p = _params(args)
    build_model_report(Path(args.in_dir), args.scene, p["tool_train"]["variants"], args.sweep or [])


def cmd_predict(args) -> None:
    from tactilepipe.tool.predict import stream_predictions
    p = _params(args)
    stream_predictions(Path(args.checkpoint), Path(args.trial), args.format, p, limit=args.limit)


def _session_lifts(p: dict, raw_root: Path, shard_root: Path):
    import pandas as pd
    from tactilepipe.volume.simulate import read_session_labels
    rows = []
    for session in p["volume_sessions"]:
        for row in read_session_labels(raw_root / session):
            stem = Path(row["bag"]).stem
            rows.append({"lift": f"{session}/{stem}", "session": session, "volume_ml": row["volume_ml"],
                         "set": row["set"], "shard": str(shard_root / session / f"{stem}.parquet")})
    return pd.DataFrame(rows)


def cmd_dataset(args) -> None:
    from tactilepipe.atomic import write_parquet, write_text
    from tactilepipe.volume.dataset import build_dataset
    p = _params(args)
    lifts = _session_lifts(p, Path(args.raw_root), Path(args.shard_root))
    data, qc = build_dataset(lifts, p["segment"], p["papillarray_axes"])
    write_parquet(args.out, data)
    write_text(args.qc, qc.to_csv(index=False))


def cmd_split(args) -> None:
    import pandas as pd
    from tactilepipe.atomic import write_json
    from tactilepipe.volume.folds import make_folds
    p = _params(args)
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
    p = _params(args)
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
    p = _params(args)
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
    p = _params(args)
    data = pd.read_parquet(args.dataset)
    folds = json.loads(Path(args.folds).read_text())
    res = sweep(data, folds, p["volume_sensor"], p["baseline"])
    out = Path(args.out_dir)
    write_parquet(out / "predictions.parquet", res["predictions"])
    write_text(out / "folds.csv", res["summary"].to_csv(index=False))
    write_text(out / "mu_curve.csv", res["curve"].to_csv(index=False))
    write_json(out / "mu.json", {"mu_star": res["mu_star"], "optima": res["optima"].to_dict("records")})


def cmd_report(args) -> None:
    p = _params(args)
    if args.what == "volume":
        from tactilepipe.volume.report import build_report
        build_report(Path(args.in_dir), p, Path(args.raw_root), Path(args.shard_root))
    elif args.what == "drift":
        from tactilepipe.drift.analyse import run
        run([Path(s) for s in args.shards], Path(args.in_dir), p)
    else:
        from tactilepipe.tool.report_data import build_data_report
        label = "normal" if args.what == "tool_normal" else "shear"
        build_data_report(Path(args.in_dir) / "data", Path(args.in_dir), label, p["tool_split"]["level_n"])


# --- argument parsing -------------------------------------------------------------------------

def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tactilepipe", description=__doc__.splitlines()[0])
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--params", default="params.yaml", help="parameter file (default: params.yaml)")
    common.add_argument("--scale", help="smoke | default | paper (overrides params.yaml)")
    common.add_argument("--override", help="JSON object merged over params.yaml before validation")
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

    s = sub.add_parser("tool-dataset", parents=[common], help="sync frames and force, references -> arrays")
    s.add_argument("--kind", choices=["normal", "shear"], required=True)
    s.add_argument("--shards", nargs="+", required=True)
    s.add_argument("--out-dir", required=True)
    s.set_defaults(func=cmd_tool_dataset)

    s = sub.add_parser("tool-split", parents=[common], help="train/validation/test split of a tool dataset")
    s.add_argument("--data-dir", required=True)
    s.add_argument("--split", choices=["frame", "trial", "loto", "lopo"], required=True)
    s.add_argument("--label", choices=["normal", "shear"], required=True)
    s.add_argument("--out", required=True)
    s.set_defaults(func=cmd_tool_split)

    s = sub.add_parser("tool-train", parents=[common], help="train one tool-force model variant, predict its test set")
    s.add_argument("--scene", choices=["tool_normal", "tool_shear"], required=True)
    s.add_argument("--variant", choices=["full", "no_ref", "single", "no_gam"], required=True)
    s.add_argument("--data-dir", required=True)
    s.add_argument("--split", required=True, help="split file (results/<scene>/splits/<name>.json)")
    s.add_argument("--out-dir", required=True)
    s.add_argument("--depth", type=int, choices=[18, 34, 50, 101], help="ResNet depth (default: params)")
    s.add_argument("--image-size", type=int, help="train on frames downscaled to this size (default: data size)")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_tool_train)

    s = sub.add_parser("tool-report", parents=[common], help="metrics.json, tables and figures of the tool models")
    s.add_argument("--scene", choices=["tool_normal", "tool_shear"], required=True)
    s.add_argument("--in-dir", required=True)
    s.add_argument("--sweep", nargs="*", help="extra runs (backbone/size) for the error-against-run-time plot")
    s.set_defaults(func=cmd_tool_report)

    s = sub.add_parser("predict", parents=[common], help="stream a recorded trial through a trained model")
    s.add_argument("--checkpoint", required=True, help="e.g. results/tool_normal/models/full/best.pt")
    s.add_argument("--trial", required=True, help="trial folder or bag")
    s.add_argument("--format", choices=["native", "public", "ros"], default="native")
    s.add_argument("--limit", type=int, help="stop after this many frame pairs")
    s.set_defaults(func=cmd_predict)

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

    s = sub.add_parser("report", parents=[common], help="metrics.json, tables and figures of a scene")
    s.add_argument("what", choices=["volume", "drift", "tool_normal", "tool_shear"])
    s.add_argument("--in-dir", required=True, help="the scene's results folder")
    s.add_argument("--raw-root", default="raw/volume")
    s.add_argument("--shard-root", default="results/volume/shards")
    s.add_argument("--shards", nargs="*", default=[], help="drift: the recordings' shards")
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
