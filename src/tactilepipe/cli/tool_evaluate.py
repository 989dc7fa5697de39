"""Stage of study 000 on its own data: evaluate a checkpoint (ours or the published weights)."""

from __future__ import annotations

import json
from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.core.errors import TactilepipeError
from tactilepipe.tool.checks import check as tool_check
from tactilepipe.tool.scenes import TOOL_SCENES


@command("tool-evaluate", "evaluate a checkpoint (ours or the public code's) on a tool dataset",
         checks=(tool_check,),
         params=("tool_train.device", "public_data.files"),
         args=(arg("--checkpoint", required=True, help="best.pt, or a public best_model_*.pth"),
               arg("--expect", metavar="NAME", help="first check the checkpoint's size and sha256 against params.yaml "
                                                    "public_data.files.NAME"),
               arg("--scene", choices=list(TOOL_SCENES), required=True), arg("--data-dir", required=True),
               arg("--split", help="split file: evaluate its test set"),
               arg("--all-frames", action="store_true", help="evaluate every frame of the data set"),
               arg("--contaminated", action="store_true",
                   help="label the result contaminated (the weights were trained on these frames)"),
               arg("--out-dir", required=True)))
def cmd_tool_evaluate(args, p) -> None:
    from tactilepipe.tool.report.study000 import evaluate_checkpoint
    if args.expect:
        from tactilepipe.tool.formats.public_archive import verify_listed
        verify_listed(args.checkpoint, p["public_data"]["files"], args.expect, "--expect")
    if not (args.all_frames or args.split):
        raise TactilepipeError("tool-evaluate: give --split SPLIT_JSON (its test set) or --all-frames")
    split = None if args.all_frames else Path(args.split)
    result = evaluate_checkpoint(Path(args.checkpoint), Path(args.data_dir), args.scene, Path(args.out_dir), split,
                                 args.contaminated, p["tool_train"]["device"])
    print(json.dumps({k: result[k] for k in ("source", "frames", "n", "mae", "rmse", "r2", "contaminated")}))
