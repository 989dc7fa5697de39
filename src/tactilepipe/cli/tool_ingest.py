"""Stage of the tool study: one recorded trial into a Parquet shard, its labels witnessed."""

from __future__ import annotations

import json

from tactilepipe.cli.registry import arg, command
from tactilepipe.tool.checks import check as tool_check


@command("tool-ingest", "tool trial (native, public or ROS) -> Parquet shard",
         checks=(tool_check,),
         params=("tool_ingest",),
         args=(arg("trial", help="trial folder or bag"), arg("--format", choices=["native", "public", "ros"], required=True),
               arg("--out", required=True)))
def cmd_tool_ingest(args, p) -> None:
    from tactilepipe.tool.formats.trials import open_trial
    from tactilepipe.tool.data.ingest import ingest_trial
    ti = p["tool_ingest"]
    raw = open_trial(args.trial, args.format, ti["ros_topics"])
    info = ingest_trial(raw, args.out, ti["stored_size"], ti)
    print(json.dumps({k: info[k] for k in ("trial", "frames", "force_samples", "clock", "drops")}))
