"""Stages of the sensor-drift study: simulate the drift session and analyse it."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.common import run_parallel
from tactilepipe.cli.registry import arg, command
from tactilepipe.papillarray import checks as papillarray_checks

# the cross-key checks a stage runs on params.yaml by hand: its sensor's (the workflow runs every
# study's: pipeline/studies.py)
DRIFT_CHECKS = (papillarray_checks.check,)


# The drift rig is the lift rig's sensor: the simulator reads the sensor's keys of simulate_volume,
# not the lift's, so a change of grip or container re-simulates the lifts only.
@command("drift-simulate", "write the simulated drift session (ROS1 bags and session.json)",
         checks=DRIFT_CHECKS,
         params=("seed", "simulate_drift", "simulate_volume.noise_std_n", "simulate_volume.bias_residual_std_n",
                 "simulate_volume.drift_inf_n", "simulate_volume.drift_per_kg_n", "simulate_volume.drift_tau_s",
                 "simulate_volume.contact_tilt_std_deg", "simulate_volume.pillar_height_steps_mm",
                 "simulate_volume.pillar_pitch_mm", "simulate_volume.pillar_travel_mm",
                 "simulate_volume.pillar_normal_stiffness_n_per_mm",
                 "simulate_volume.pillar_tangential_stiffness_n_per_mm", "simulate_volume.creep_fractions",
                 "simulate_volume.creep_tau_s", "simulate_volume.creep_integrator", "simulate_volume.creep_substeps"),
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
         checks=DRIFT_CHECKS,
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
