"""Stages of the tool-force study: simulate and ingest trials, sync them into a data set, split,
train each model variant, report; and the QC and streaming commands around them."""

from __future__ import annotations

import json
from pathlib import Path

from tactilepipe.cli.common import stage_params, run_parallel
from tactilepipe.tool.model.variants import VARIANTS
from tactilepipe.tool.scenes import TOOL_SCENES, scene_label


def cmd_simulate_tool(args) -> None:
    from tactilepipe.tool import sim as tsim
    from tactilepipe.tool.sim.background import load_background
    p = stage_params(args, "seed", "simulate_tool")
    load_background(p["simulate_tool"]["render"]["background"])     # a bad frame stops here, before any trial
    out = Path(args.out_dir)
    chosen = [t for t in tsim.session_plan(p) if not args.lifts or t.name in args.lifts]
    tsim.write_session_calibration(out, p)
    run_parallel([(tsim.write_trial, out, t, p) for t in chosen], args.jobs, "simulate tool")


def cmd_ingest_tool(args) -> None:
    from tactilepipe.tool.formats.trials import open_trial
    from tactilepipe.tool.data.ingest import ingest_trial
    p = stage_params(args, "tool_ingest")
    ti = p["tool_ingest"]
    raw = open_trial(args.trial, args.format, ti["ros_topics"])
    info = ingest_trial(raw, args.out, ti["image_size"], ti)
    print(json.dumps({k: info[k] for k in ("trial", "frames", "force_samples", "clock", "drops")}))


def cmd_tool_clock_figure(args) -> None:
    from tactilepipe.tool.data.clock_report import clock_figure
    n = clock_figure([Path(s) for s in args.shards], Path(args.out))
    print(json.dumps({"figure": args.out, "trials_plotted": n}))


def cmd_realism(args) -> None:
    from tactilepipe.tool.sim import realism
    result = realism.compare(args.real_dir, args.sim_dir, args.real_ref, args.sim_ref, args.max_frames)
    print(realism.report(result), end="")
    realism.figure(result, args.figure)
    print(f"figure: {args.figure}")


def cmd_tool_dataset(args) -> None:
    from tactilepipe.tool.data.dataset import build_tool_dataset
    p = stage_params(args, "tool_sync")
    build_tool_dataset([Path(s) for s in args.shards], args.kind, Path(args.out_dir), p["tool_sync"])


def cmd_tool_split(args) -> None:
    import pandas as pd
    from tactilepipe.core.atomic import write_json
    from tactilepipe.tool.data.splits import make_split
    p = stage_params(args, "seed", "tool_split.fractions", "tool_split.holdout_pose")
    sp = p["tool_split"]
    samples = pd.read_parquet(Path(args.data_dir) / "samples.parquet")
    split = make_split(samples, args.split, args.label, p["seed"], tuple(sp["fractions"]), sp["holdout_pose"])
    write_json(args.out, split)


def cmd_tool_train(args) -> None:
    from tactilepipe.tool.model.kernels import use_kernels
    p = stage_params(args, "seed", "tool_train.lr", "tool_train.lr_schedule", "tool_train.batch_size",
                "tool_train.max_epochs", "tool_train.patience", "tool_train.max_train_batches_per_epoch",
                "tool_train.bn_recalibration_batches", "tool_train.device", "tool_train.amp", "tool_train.num_threads",
                "tool_train.gam_channel_gate", "tool_train.width", "tool_train.kernels")
    use_kernels(p["tool_train"]["kernels"])          # before torch loads: the portable pins are read then
    from tactilepipe.tool.model.run import train_and_predict
    result = train_and_predict(args.scene, Path(args.data_dir), Path(args.split), Path(args.out_dir), args.variant,
                               args.depth, args.image_size, p["tool_train"], p["seed"], progress=not args.quiet)
    print(json.dumps({k: result[k] for k in ("variant", "depth", "image_size", "mae", "rmse", "r2", "train_s",
                                             "latency_ms")}))


def cmd_tool_report(args) -> None:
    from tactilepipe.tool.report.models import build_model_report
    p = stage_params(args, "tool_train.variants", "tool_train.split", "tool_train.depth", "tool_train.image_size",
                "tool_train.sweep")
    build_model_report(Path(args.in_dir), args.scene, p["tool_train"], args.runs)
    from tactilepipe.cli.provenance import write_scene_provenance
    write_scene_provenance(args, Path(args.in_dir))


def cmd_predict(args) -> None:
    from tactilepipe.tool.model.stream import prepare_process, stream_predictions
    p = stage_params(args, "tool_ingest.ros_topics", "tool_ingest.image_size", "predict")
    prepare_process(p)                               # before torch loads: the portable pins are read then
    stream_predictions(Path(args.checkpoint), Path(args.trial), args.format, p, limit=args.limit,
                       label_range=args.label_range)


def cmd_portability(args) -> None:
    from tactilepipe.core.atomic import write_json
    from tactilepipe.tool.report import portability
    results, record = Path(args.results), Path(args.record)
    if args.new:
        rec = portability.new_record(results)
        write_json(record, rec)
        print(f"{record}: started with {len(rec['runs'])} runs on {portability.describe(rec['machines'][0]['kind'])}")
        return
    for note in portability.check(results, record):
        print(f"{record}: {note}")


def cmd_report_tool_data(args) -> None:
    from tactilepipe.tool.report.data import build_data_report
    p = stage_params(args, "tool_split.level_n")
    label = scene_label(args.what)
    build_data_report(Path(args.in_dir) / "data", Path(args.in_dir), label, p["tool_split"]["level_n"])


def add_parsers(sub, common, provenance) -> None:
    """This study's sub-commands, on the parser's ``sub``; ``common`` and ``provenance`` are the
    shared option groups."""
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
    s.add_argument("--scene", choices=list(TOOL_SCENES), required=True)
    s.add_argument("--variant", choices=list(VARIANTS), required=True)
    s.add_argument("--data-dir", required=True)
    s.add_argument("--split", required=True, help="split file (results/<scene>/splits/<name>.json)")
    s.add_argument("--out-dir", required=True)
    s.add_argument("--depth", type=int, choices=[18, 34, 50, 101], required=True, help="ResNet depth")
    s.add_argument("--image-size", type=int, required=True, help="train on frames downscaled to this size")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_tool_train)

    s = sub.add_parser("tool-report", parents=[common, provenance], help="metrics.json, tables and figures of the tool models")
    s.add_argument("--scene", choices=list(TOOL_SCENES), required=True)
    s.add_argument("--in-dir", required=True)
    s.add_argument("--runs", nargs="+", required=True,
                   help="every run of the scene (results/<scene>/models/<run>; names as in tool/runs.py)")
    s.set_defaults(func=cmd_tool_report)

    s = sub.add_parser("portability", help="compare a smoke build's tool runs with results/portability.json: the "
                                           "same bytes on every machine kind (adds this one when new)")
    s.add_argument("--results", default="results", help="results folder of a smoke-scale build (make smoke)")
    s.add_argument("--record", default="results/portability.json", help="the record to check and extend")
    s.add_argument("--new", action="store_true",
                   help="start the record again from this build and machine (after a deliberate change of the "
                        "training code, its parameters or the data)")
    s.set_defaults(func=cmd_portability)

    s = sub.add_parser("predict", parents=[common], help="stream a recorded trial through a trained model")
    s.add_argument("--checkpoint", required=True, help="e.g. results/tool_normal/models/full/best.pt")
    s.add_argument("--trial", required=True, help="trial folder or bag")
    s.add_argument("--format", choices=["native", "public", "ros"], default="native")
    s.add_argument("--limit", type=int, help="stop after this many frame pairs")
    s.add_argument("--label-range", nargs=2, type=float, metavar=("MIN_N", "MAX_N"),
                   help="a public-code normal-force checkpoint: the force range (N) its outputs were scaled to "
                        "(the min and max over its training data set)")
    s.set_defaults(func=cmd_predict)
