"""Stage of the tool study: the train, validation and test trials of a data set."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.tool.checks import check as tool_check


@command("tool-split", "train/validation/test split of a tool dataset",
         checks=(tool_check,),
         params=("seed", "tool_split.fractions", "tool_split.holdout_pose"),
         args=(arg("--data-dir", required=True),
               arg("--split", required=True, help="frame | public_frame | trial | lopo, each with an optional _r<k> "
                                                  "(repeat k); or loto_<tool>"),
               arg("--label", choices=["normal", "shear"], required=True), arg("--out", required=True)))
def cmd_tool_split(args, p) -> None:
    import pandas as pd
    from tactilepipe.core.atomic import write_json
    from tactilepipe.tool.data.splits import make_split
    sp = p["tool_split"]
    samples = pd.read_parquet(Path(args.data_dir) / "samples.parquet")
    split = make_split(samples, args.split, args.label, p["seed"], tuple(sp["fractions"]), sp["holdout_pose"])
    write_json(args.out, split)
