"""Stage of the tool study: the QC page and data figures of a scene."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.cli.tool_args import SCENE
from tactilepipe.tool.checks import check as tool_check
from tactilepipe.tool.scenes import scene_label


@command("tool-data-report", "QC report and data figures of a tool scene",
         checks=(tool_check,),
         params=("tool_split.level_n",),
         args=(SCENE, arg("--in-dir", required=True, help="the scene's results folder")))
def cmd_tool_data_report(args, p) -> None:
    from tactilepipe.tool.report.data import build_data_report
    label = scene_label(args.scene)
    build_data_report(Path(args.in_dir) / "data", Path(args.in_dir), label, p["tool_split"]["level_n"])
