"""Stage of the tool study: write a simulated session in the rig's layout."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.common import run_parallel
from tactilepipe.cli.registry import arg, command
from tactilepipe.tool.checks import check as tool_check


@command("tool-simulate", "write a simulated tool session (the rig's layout: DIGIT frames, Nano17 serial log)",
         checks=(tool_check,),
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
