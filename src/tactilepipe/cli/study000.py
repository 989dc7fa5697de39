"""Stages that run the tool-force study on its own published data: unpack the archives, evaluate a
checkpoint (ours or the published weights), and set the protocols beside the paper's table."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.core.errors import TactilepipeError
from tactilepipe.tool import checks as tool_checks
from tactilepipe.tool.scenes import TOOL_SCENES

# the cross-key checks a stage runs on params.yaml by hand: its study's (the workflow runs every
# study's: pipeline/studies.py)
TOOL_CHECKS = (tool_checks.check,)


@command("study000-unpack", "check a study-000 archive's size and sha256, unpack it into a public-layout session",
         checks=TOOL_CHECKS,
         params=("public_data.files", "public_data.session"),
         args=(arg("archive", help="e.g. raw/downloads/data_normal.zip"),
               arg("--name", required=True, help="its entry in params.yaml public_data.files (data_normal, data_shear)"),
               arg("--raw-root", default="raw/tool", help="the session folder public_data.session is made here")))
def cmd_study000_unpack(args, p) -> None:
    from tactilepipe.tool.formats.public_archive import unpack, verify_listed, write_trials_template
    verify_listed(args.archive, p["public_data"]["files"], args.name, "--name")
    session = Path(args.raw_root) / p["public_data"]["session"]
    trials = unpack(args.archive, args.name, session)
    added = write_trials_template(session)
    print(json.dumps({"archive": args.archive, "session": str(session), "trials": len(trials),
                      "trials_csv_rows_added": len(added)}))
    if added:
        print(f"{session / 'trials.csv'}: {len(added)} trials need a tool and pose (tool, orientation_deg, "
              f"insertion_mm) before the scene can be built", file=sys.stderr)


@command("tool-evaluate", "evaluate a checkpoint (ours or the public code's) on a tool dataset",
         checks=TOOL_CHECKS,
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


@command("study000-table", "study 000's protocols (or published weights) beside the paper",
         checks=TOOL_CHECKS,
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
