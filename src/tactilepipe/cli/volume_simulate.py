"""Stage of the volume study: write a simulated session of lifts as ROS1 bags."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.common import run_parallel
from tactilepipe.cli.registry import arg, command
from tactilepipe.cli.volume_args import VOLUME_CHECKS
from tactilepipe.core.errors import TactilepipeError


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
