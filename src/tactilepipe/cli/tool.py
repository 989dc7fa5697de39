"""Stages of the tool-force study: simulate and ingest trials, sync them into a data set, split,
train each model variant, report; and the QC and streaming commands around them."""

from __future__ import annotations

import json
from pathlib import Path

from tactilepipe.cli.common import run_parallel
from tactilepipe.cli.registry import arg, command
from tactilepipe.tool import checks as tool_checks
from tactilepipe.tool.scenes import TOOL_SCENES, scene_label

# the cross-key checks a stage runs on params.yaml by hand: its study's (the workflow runs every
# study's: pipeline/studies.py)
TOOL_CHECKS = (tool_checks.check,)

SCENE = arg("--scene", choices=list(TOOL_SCENES), required=True)


@command("tool-simulate", "write a simulated tool session (the rig's layout: DIGIT frames, Nano17 serial log)",
         checks=TOOL_CHECKS,
         params=("seed", "simulate_tool"),
         args=(arg("--out-dir", required=True, help="session folder, e.g. raw/tool/sim-default"),
               arg("--trials", nargs="*", help="only these trials (default: the whole session)"),
               arg("--jobs", type=int, default=1, help="worker processes (default 1)")))
def cmd_tool_simulate(args, p) -> None:
    from tactilepipe.tool import sim as tsim
    from tactilepipe.tool.sim.background import load_background
    load_background(p["simulate_tool"]["render"]["background"])     # a bad frame stops here, before any trial
    out = Path(args.out_dir)
    chosen = [t for t in tsim.session_plan(p) if not args.trials or t.name in args.trials]
    tsim.write_session_calibration(out, p)
    run_parallel([(tsim.write_trial, out, t, p) for t in chosen], args.jobs, "simulate tool")


@command("tool-ingest", "tool trial (native, public or ROS) -> Parquet shard",
         checks=TOOL_CHECKS,
         params=("tool_ingest",),
         args=(arg("trial", help="trial folder or bag"), arg("--format", choices=["native", "public", "ros"], required=True),
               arg("--out", required=True)))
def cmd_tool_ingest(args, p) -> None:
    from tactilepipe.tool.formats.trials import open_trial
    from tactilepipe.tool.data.ingest import ingest_trial
    ti = p["tool_ingest"]
    raw = open_trial(args.trial, args.format, ti["ros_topics"])
    info = ingest_trial(raw, args.out, ti["stored_size"], ti)
    print(json.dumps({k: info[k] for k in ("trial", "frames", "force_samples", "clock", "drops")}))


@command("tool-clock-figure", "QC figure: each native trial's clock correlation against lag",
         args=(arg("--shards", nargs="+", required=True, help="a session's tool shards"),
               arg("--out", required=True, help="PNG to write")))
def cmd_tool_clock_figure(args, p) -> None:
    from tactilepipe.tool.data.clock_report import clock_figure
    n = clock_figure([Path(s) for s in args.shards], Path(args.out))
    print(json.dumps({"figure": args.out, "trials_plotted": n}))


@command("realism", "compare two folders of tactile frames (real vs simulated): statistics and a figure",
         args=(arg("real_dir", help="folder of real frames (JPEG/PNG, searched recursively; portrait or landscape)"),
               arg("sim_dir", help="folder of simulated frames (e.g. raw/tool/sim-default)"),
               arg("--real-ref", help="reference frame of the real folder (default: each sub-folder's first frame)"),
               arg("--sim-ref", help="reference frame of the simulated folder (default: each sub-folder's first frame)"),
               arg("--max-frames", type=int, default=2000, help="read at most this many frames per folder"),
               arg("--figure", default="realism.png", help="figure to write (montage and histograms)")))
def cmd_realism(args, p) -> None:
    from tactilepipe.tool.sim import realism
    result = realism.compare(args.real_dir, args.sim_dir, args.real_ref, args.sim_ref, args.max_frames)
    print(realism.report(result), end="")
    realism.figure(result, args.figure)
    print(f"figure: {args.figure}")


@command("tool-dataset", "sync frames and force, references -> arrays",
         checks=TOOL_CHECKS,
         params=("tool_sync",), graph=("tool_sessions",),
         args=(arg("--kind", choices=["normal", "shear"], required=True), arg("--shards", nargs="+", required=True),
               arg("--out-dir", required=True)))
def cmd_tool_dataset(args, p) -> None:
    from tactilepipe.tool.data.dataset import build_tool_dataset
    build_tool_dataset([Path(s) for s in args.shards], args.kind, Path(args.out_dir), p["tool_sync"])


@command("tool-split", "train/validation/test split of a tool dataset",
         checks=TOOL_CHECKS,
         params=("seed", "tool_split.fractions", "tool_split.holdout_pose"),
         args=(arg("--data-dir", required=True),
               arg("--split", required=True, help="frame | public_frame | trial | lopo, each with an optional _r<k> "
                                                  "(repeat k); or loto_<tool>"),
               arg("--label", choices=["normal", "shear"], required=True), arg("--out", required=True)))
def cmd_tool_split(args, p) -> None:
    import pandas as pd
    from tactilepipe.core.atomic import write_json
    from tactilepipe.tool.data.splits import make_split
    sp = p["tool_split"]
    samples = pd.read_parquet(Path(args.data_dir) / "samples.parquet")
    split = make_split(samples, args.split, args.label, p["seed"], tuple(sp["fractions"]), sp["holdout_pose"])
    write_json(args.out, split)


@command("tool-train", "train one tool-force model run, predict its test set",
         checks=TOOL_CHECKS,
         params=("seed", "tool_train.lr", "tool_train.lr_schedule", "tool_train.batch_size", "tool_train.max_epochs",
                 "tool_train.patience", "tool_train.max_train_batches_per_epoch", "tool_train.bn_recalibration_batches",
                 "tool_train.device", "tool_train.amp", "tool_train.num_threads", "tool_train.gam_channel_gate",
                 "tool_train.width", "tool_train.kernels"),
         # the run's own values (variant and its architecture, split name, depth, input size) are in its
         # stamp, results/<build>/params/tool-train/<run>.json (pipeline/stamps.py run_stamp_text)
         args=(SCENE, arg("--data-dir", required=True),
               arg("--split", required=True, help="split file (results/<build>/<scene>/splits/<name>.json)"),
               arg("--out-dir", required=True),
               arg("--run", help="by hand, without --stamp: the run to train (a name as in tool/runs.py, e.g. full, "
                                 "no_gam_r1, full_d18_s8), defined by params.yaml as the workflow defines it"),
               arg("--quiet", action="store_true", help="no progress bar (one line per epoch is still written to "
                                                           "stderr; the bar is off anyway when stderr is no terminal)")))
def cmd_tool_train(args, p) -> None:
    run = _train_run(args)
    from tactilepipe.tool.model.kernels import use_kernels
    use_kernels(p["tool_train"]["kernels"])          # before torch loads: the portable pins are read then
    from tactilepipe.tool.model.run import train_and_predict
    result = train_and_predict(args.scene, Path(args.data_dir), Path(args.split), Path(args.out_dir), run,
                               p["tool_train"], p["seed"], progress=not args.quiet)
    print(json.dumps({k: result[k] for k in ("variant", "depth", "image_size", "mae", "rmse", "r2", "train_s",
                                             "latency_ms")}))


def _train_run(args) -> dict:
    """The run a tool-train job trains: from its stamp (the workflow's), or by hand from --run and
    params.yaml, through the same definition (tool/runs.py run_definition)."""
    from tactilepipe.core.errors import ArgumentError
    from tactilepipe.pipeline.stamps import run_of_stamp
    if args.stamp:
        run = run_of_stamp(args.stamp)
        if args.run and args.run != run["name"]:
            raise ArgumentError(f"--run {args.run}: the stamp {args.stamp} is run {run['name']}'s")
        return run
    if not args.run:
        raise ArgumentError("give the run's stamp (--stamp results/<build>/params/tool-train/<run>.json) or, by hand, "
                            "--run NAME")
    from tactilepipe.cli.common import param_overrides
    from tactilepipe.core.config import load_params
    from tactilepipe.tool.runs import run_definition
    return run_definition(load_params(args.params, param_overrides(args)), args.run)


@command("tool-model-report", "scores.json, metrics.json, tables and figures of a tool scene's models",
         checks=TOOL_CHECKS,
         params=("tool_train.variants", "tool_train.split", "tool_train.depth", "tool_train.image_size",
                 "tool_train.sweep", "tool_variants", "tool_report.equivalence_margin"),
         graph=("tool_sessions", "tool_train.loto", "tool_split.repeats"),
         args=(SCENE, arg("--in-dir", required=True),
               arg("--runs", nargs="+", required=True,
                   help="every run of the scene (results/<build>/<scene>/models/<run>; names as in tool/runs.py)")),
         provenance=True)
def cmd_tool_model_report(args, p) -> None:
    from tactilepipe.tool.report.models import build_model_report
    build_model_report(Path(args.in_dir), args.scene, p["tool_train"], p["tool_variants"], args.runs,
                       p["tool_report"]["equivalence_margin"])
    from tactilepipe.cli.provenance import write_scene_provenance
    write_scene_provenance(args, Path(args.in_dir))


@command("predict", "stream a recorded trial through a trained model",
         checks=TOOL_CHECKS,
         params=("tool_ingest.ros_topics", "tool_ingest.stored_size", "predict"),
         args=(arg("--checkpoint", required=True, help="e.g. results/default/tool_normal/models/full/best.pt"),
               arg("--trial", required=True, help="trial folder or bag"),
               arg("--format", choices=["native", "public", "ros"], default="native"),
               arg("--limit", type=int, help="stop after this many frame pairs"),
               arg("--label-range", nargs=2, type=float, metavar=("MIN_N", "MAX_N"),
                   help="a public-code normal-force checkpoint: the force range (N) its outputs were scaled to "
                        "(the min and max over its training data set)")))
def cmd_predict(args, p) -> None:
    from tactilepipe.tool.model.stream import prepare_process, stream_predictions
    prepare_process(p)                               # before torch loads: the portable pins are read then
    stream_predictions(Path(args.checkpoint), Path(args.trial), args.format, p, limit=args.limit,
                       label_range=args.label_range)


@command("portability", "compare a smoke build's tool runs with results/portability.json: the same bytes on "
                        "every machine kind (adds this one when new)",
         args=(arg("--results", default="results/smoke", help="results folder of a smoke-scale build (make smoke)"),
               arg("--record", default="results/portability.json", help="the record to check and extend"),
               arg("--new", action="store_true",
                   help="start the record again from this build and machine (after a deliberate change of the "
                        "training code, its parameters or the data)")))
def cmd_portability(args, p) -> None:
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


@command("tool-data-report", "QC report and data figures of a tool scene",
         checks=TOOL_CHECKS,
         params=("tool_split.level_n",),
         args=(SCENE, arg("--in-dir", required=True, help="the scene's results folder")))
def cmd_tool_data_report(args, p) -> None:
    from tactilepipe.tool.report.data import build_data_report
    label = scene_label(args.scene)
    build_data_report(Path(args.in_dir) / "data", Path(args.in_dir), label, p["tool_split"]["level_n"])
