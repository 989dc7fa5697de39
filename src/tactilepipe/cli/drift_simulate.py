"""Stage of the drift study: write the simulated drift session. Its cross-key checks are its sensor's
(the workflow runs every study's: tactilepipe/studies.py)."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.common import run_parallel
from tactilepipe.cli.registry import arg, command
from tactilepipe.papillarray.checks import check as papillarray_check


# The drift rig is the lift rig's sensor: the simulator reads the sensor's keys of simulate_volume,
# not the lift's, so a change of grip or container re-simulates the lifts only.
@command("drift-simulate", "write the simulated drift session (ROS1 bags and session.json)",
         checks=(papillarray_check,),
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
