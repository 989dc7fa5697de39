"""Stage of the tool study: train one model run and predict its test set."""

from __future__ import annotations

import json
from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.cli.tool_args import SCENE
from tactilepipe.tool.checks import check as tool_check


@command("tool-train", "train one tool-force model run, predict its test set",
         checks=(tool_check,),
         # tool_train but its graph keys: those lay out the runs, and each run reads them through its own
         # definition (variant and its architecture, split name, depth, input size), under `run` in its
         # stamp, results/<build>/params/tool-train/<run>.json (pipeline/stamps.py run_stamp_text)
         params=("seed", "tool_train"),
         graph=("tool_train.variants", "tool_train.split", "tool_train.loto", "tool_train.depth",
                "tool_train.image_size", "tool_train.sweep"),
         args=(SCENE, arg("--data-dir", required=True),
               arg("--split", required=True, help="split file (results/<build>/<scene>/splits/<name>.json)"),
               arg("--out-dir", required=True),
               arg("--run", help="by hand, without --stamp: the run to train (a name as in tool/runs.py, e.g. full, "
                                 "no_gam_r1, full_d18_s8), defined by params.yaml as the workflow defines it"),
               arg("--quiet", action="store_true", help="no progress bar (one line per epoch is still written to "
                                                           "stderr; the bar is off anyway when stderr is no terminal)")))
def cmd_tool_train(args, p) -> None:
    run = _train_run(args)
    from tactilepipe.tool.model.kernels import use_kernels
    use_kernels(p["tool_train"]["kernels"])          # before torch loads: the portable pins are read then
    from tactilepipe.tool.model.run import train_and_predict
    result = train_and_predict(args.scene, Path(args.data_dir), Path(args.split), Path(args.out_dir), run,
                               p["tool_train"], p["seed"], progress=not args.quiet)
    print(json.dumps({k: result[k] for k in ("variant", "depth", "image_size", "mae", "rmse", "r2", "train_s",
                                             "latency_ms")}))


def _train_run(args) -> dict:
    """The run a tool-train job trains: from its stamp (the workflow's), or by hand from --run and
    params.yaml, through the same definition (tool/runs.py run_definition)."""
    from tactilepipe.core.errors import ArgumentError
    from tactilepipe.pipeline.stamps import run_of_stamp
    if args.stamp:
        run = run_of_stamp(args.stamp)
        if args.run and args.run != run["name"]:
            raise ArgumentError(f"--run {args.run}: the stamp {args.stamp} is run {run['name']}'s")
        return run
    if not args.run:
        raise ArgumentError("give the run's stamp (--stamp results/<build>/params/tool-train/<run>.json) or, by hand, "
                            "--run NAME")
    from tactilepipe.cli.common import param_overrides
    from tactilepipe.core.config import load_params
    from tactilepipe.tool.runs import run_definition
    return run_definition(load_params(args.params, param_overrides(args)), args.run)
