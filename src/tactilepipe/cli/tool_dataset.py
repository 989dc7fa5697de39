"""Stage of the tool study: a session's shards synced into a data set of frame pairs and labels."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.tool.checks import check as tool_check


@command("tool-dataset", "sync frames and force, references -> arrays",
         checks=(tool_check,),
         params=("tool_sync",), graph=("tool_sessions",),
         args=(arg("--kind", choices=["normal", "shear"], required=True), arg("--shards", nargs="+", required=True),
               arg("--out-dir", required=True)))
def cmd_tool_dataset(args, p) -> None:
    from tactilepipe.tool.data.dataset import build_tool_dataset
    build_tool_dataset([Path(s) for s in args.shards], args.kind, Path(args.out_dir), p["tool_sync"])
