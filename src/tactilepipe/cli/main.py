"""The command line: one parser over every study's stages; errors print one line, no traceback."""

from __future__ import annotations

import argparse
import sys

from tactilepipe.cli import compare, drift, rig, study000, tool, volume
from tactilepipe.core.errors import TactilepipeError
from tactilepipe.tool.scenes import TOOL_SCENES


def cmd_simulate(args) -> None:
    {"volume": volume.cmd_simulate_volume, "tool": tool.cmd_simulate_tool, "drift": drift.cmd_simulate_drift}[args.what](args)


def cmd_report(args) -> None:
    {"volume": volume.cmd_report_volume, "drift": drift.cmd_report_drift}.get(args.what, tool.cmd_report_tool_data)(args)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tactilepipe", description="every pipeline stage of tactilepipe")
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

    s = sub.add_parser("report", parents=[common, provenance], help="metrics.json, tables and figures of a scene")
    s.add_argument("what", choices=["volume", "drift", *TOOL_SCENES])
    s.add_argument("--in-dir", required=True, help="the scene's results folder")
    s.add_argument("--raw-root", default="raw/volume")
    s.add_argument("--shard-root", default="results/volume/shards")
    s.add_argument("--shards", nargs="*", default=[], help="drift: the recordings' shards")
    s.add_argument("--session-meta", help="drift: the session's session.json (reference weight)")
    s.set_defaults(func=cmd_report)

    for study in (volume, tool, study000, compare, rig):   # drift has only `simulate drift` and `report drift`
        study.add_parsers(sub, common, provenance)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        status = args.func(args)          # a command may return an exit status (diff: 1 on a regression)
    except TactilepipeError as exc:
        print(f"tactilepipe {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        # the machine, not the data: a full disk, a read-only or forbidden folder, a size limit,
        # a file that vanished. One line naming the file, no traceback.
        print(f"tactilepipe {args.command}: error: {_os_error_line(exc)}", file=sys.stderr)
        return 1
    return status or 0


def _os_error_line(exc: OSError) -> str:
    """'<path>: <problem>' of an OSError (pyarrow and numpy often leave filename unset)."""
    import os
    problem = exc.strerror or (os.strerror(exc.errno) if exc.errno else str(exc) or type(exc).__name__)
    if exc.filename is None:
        return f"{problem} ({str(exc).strip() or type(exc).__name__})" if str(exc) != problem else problem
    where = f"{exc.filename} -> {exc.filename2}" if exc.filename2 else str(exc.filename)
    return f"{where}: {problem}"
