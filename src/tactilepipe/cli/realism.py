"""Command of the tool study: real against simulated DIGIT frames, side by side."""

from __future__ import annotations

from tactilepipe.cli.registry import arg, command


@command("realism", "compare two folders of tactile frames (real vs simulated): statistics and a figure",
         args=(arg("real_dir", help="folder of real frames (JPEG/PNG, searched recursively; portrait or landscape)"),
               arg("sim_dir", help="folder of simulated frames (e.g. raw/tool/sim-default)"),
               arg("--real-ref", help="reference frame of the real folder (default: each sub-folder's first frame)"),
               arg("--sim-ref", help="reference frame of the simulated folder (default: each sub-folder's first frame)"),
               arg("--max-frames", type=int, default=2000, help="read at most this many frames per folder"),
               arg("--figure", default="realism.png", help="figure to write (montage and histograms)")))
def cmd_realism(args, p) -> None:
    from tactilepipe.tool.sim import realism
    result = realism.compare(args.real_dir, args.sim_dir, args.real_ref, args.sim_ref, args.max_frames)
    print(realism.report(result), end="")
    realism.figure(result, args.figure)
    print(f"figure: {args.figure}")
