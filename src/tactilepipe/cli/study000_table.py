"""Stage of study 000 on its own data: the protocols beside the paper's table."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.tool.checks import check as tool_check


@command("study000-table", "study 000's protocols (or published weights) beside the paper",
         checks=(tool_check,),
         params=("public_data.paper",),
         args=(arg("--evals", nargs="*", default=[], help="eval.json of the runs full_public_frame, full_trial"),
               arg("--published", help="eval.json of the published weights over every frame"),
               arg("--out-dir", required=True)))
def cmd_study000_table(args, p) -> None:
    from tactilepipe.tool.report.study000 import protocol_table, published_table
    paper, out = p["public_data"]["paper"], Path(args.out_dir)
    if args.published:
        published_table(Path(args.published), paper, out)
    else:
        protocol_table({Path(e).parent.name: Path(e) for e in args.evals}, paper, out)
