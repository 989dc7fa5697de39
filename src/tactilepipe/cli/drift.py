"""Stages of the sensor-drift study: simulate the drift session and analyse it."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.common import stage_params, run_parallel


def cmd_simulate_drift(args) -> None:
    from tactilepipe.drift import simulate as dsim
    p = stage_params(args, "seed", "simulate_drift", "simulate_volume")
    out = Path(args.out_dir)
    names = args.lifts or dsim.session_plan(p)
    run_parallel([(dsim.write_drift_bag, out / f"{n}.bag", n, p) for n in names], args.jobs, "simulate drift")
    dsim.write_session_meta(out, p)


def cmd_report_drift(args) -> None:
    from tactilepipe.drift.analyse import run
    p = stage_params(args, "drift")
    run([Path(s) for s in args.shards], Path(args.session_meta), Path(args.in_dir), p)
    from tactilepipe.cli.provenance import write_scene_provenance
    write_scene_provenance(args, Path(args.in_dir))
