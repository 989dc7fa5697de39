"""Command of the tool study: stream a recorded trial through a trained model."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.tool.checks import check as tool_check


@command("predict", "stream a recorded trial through a trained model",
         checks=(tool_check,),
         params=("tool_ingest.ros_topics", "tool_ingest.stored_size", "predict"),
         args=(arg("--checkpoint", required=True, help="e.g. results/default/tool_normal/models/full/best.pt"),
               arg("--trial", required=True, help="trial folder or bag"),
               arg("--format", choices=["native", "public", "ros"], default="native"),
               arg("--limit", type=int, help="stop after this many frame pairs"),
               arg("--label-range", nargs=2, type=float, metavar=("MIN_N", "MAX_N"),
                   help="a public-code normal-force checkpoint: the force range (N) its outputs were scaled to "
                        "(the min and max over its training data set)")))
def cmd_predict(args, p) -> None:
    from tactilepipe.tool.model.stream import prepare_process, stream_predictions
    prepare_process(p)                               # before torch loads: the portable pins are read then
    stream_predictions(Path(args.checkpoint), Path(args.trial), args.format, p, limit=args.limit,
                       label_range=args.label_range)
