"""Stages of the sensor-drift study: simulate the drift session and analyse it."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.common import run_parallel
from tactilepipe.cli.registry import arg, command


@command("drift-simulate", "write the simulated drift session (ROS1 bags and session.json)",
         params=("seed", "simulate_drift", "simulate_volume"),
         args=(arg("--out-dir", required=True, help="session folder, e.g. raw/drift/sim-default"),
               arg("--lifts", nargs="*", help="only these recordings (default: the whole session)"),
               arg("--jobs", type=int, default=1, help="worker processes (default 1)")))
def cmd_drift_simulate(args, p) -> None:
    from tactilepipe.drift import simulate as dsim
    out = Path(args.out_dir)
    names = args.lifts or dsim.session_plan(p)
    run_parallel([(dsim.write_drift_bag, out / f"{n}.bag", n, p) for n in names], args.jobs, "simulate drift")
    dsim.write_session_meta(out, p)


@command("drift-report", "metrics.json, fits and figures of the drift study",
         params=("drift",), graph=("drift_session",),
         args=(arg("--in-dir", required=True, help="the scene's results folder"),
               arg("--shards", nargs="+", required=True, help="the recordings' shards"),
               arg("--session-meta", required=True, help="the session's session.json (reference weight)")),
         provenance=True)
def cmd_drift_report(args, p) -> None:
    from tactilepipe.drift.analyse import run
    run([Path(s) for s in args.shards], Path(args.session_meta), Path(args.in_dir), p)
    from tactilepipe.cli.provenance import write_scene_provenance
    write_scene_provenance(args, Path(args.in_dir))
