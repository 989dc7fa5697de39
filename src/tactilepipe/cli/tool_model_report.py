"""Stage of the tool study: a scene's scores, metrics, tables and figures over its runs."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.cli.tool_args import SCENE
from tactilepipe.tool.checks import check as tool_check


@command("tool-model-report", "scores.json, metrics/, tables and figures of a tool scene's models",
         checks=(tool_check,),
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
