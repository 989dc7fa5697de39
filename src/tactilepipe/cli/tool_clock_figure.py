"""Stage of the tool study: the QC figure of a session's force clock."""

from __future__ import annotations

import json
from pathlib import Path

from tactilepipe.cli.registry import arg, command


@command("tool-clock-figure", "QC figure: each native trial's clock correlation against lag",
         args=(arg("--shards", nargs="+", required=True, help="a session's tool shards"),
               arg("--out", required=True, help="PNG to write")))
def cmd_tool_clock_figure(args, p) -> None:
    from tactilepipe.tool.data.clock_report import clock_figure
    n = clock_figure([Path(s) for s in args.shards], Path(args.out))
    print(json.dumps({"figure": args.out, "trials_plotted": n}))
