"""Training throughput with portable kernels against native ones, side by side.

``tool_train.kernels: portable`` trades speed for bytes that do not depend on the CPU
(tool/model/kernels.py): no oneDNN, MKL's COMPATIBLE branch, ATen at AVX2, one thread. This prints
what that costs, as frame pairs per second of training (forward, backward and Adam step on random
data at the default scale's input size, batch and depth), at the paper's width (64), the default
scale's and the smoke scale's, each mode in its own process (the pins are read when torch loads),
one thread each, one after the other. The width is the lever that let the default scale train
portable: the rows show what each width costs in either mode.

Usage: python benchmarks/bench_kernels.py [--steps 30] [--small]   (--small: 2 steps, smoke row only)
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
from pathlib import Path

from tactilepipe.core.config import load_params

REPO = Path(__file__).resolve().parents[1]


def _throughput(args: tuple) -> tuple[float, dict]:
    mode, variant, depth, size, batch, gate, width, steps = args
    from tactilepipe.tool.model.kernels import use_kernels
    active = use_kernels(mode)                      # first thing in the fresh process, before torch loads
    from bench_train_jobs import train_throughput
    return train_throughput(variant, depth, size, batch, gate, width, steps=steps, num_threads=1), active


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--small", action="store_true", help="2 steps of the smoke row only: a check that it runs")
    args = ap.parse_args()
    # imported here, not at the top: a spawned worker imports this module before it chooses its
    # kernels, and portable kernels must be chosen before torch loads (network imports torch)
    from tactilepipe.tool.model.network import PAPER_WIDTH
    ctx = mp.get_context("spawn")
    print("full model; each row at its scale's input size, depth, batch and width (the paper row: the "
          "default scale's with the paper's width)")
    print(f"{'scale':8s} {'width':>5s} {'native pairs/s':>15s} {'portable pairs/s':>17s} {'portable / native':>18s}")
    default = load_params(REPO / "params.yaml")["tool_train"]
    rows = [("paper", {**default, "width": PAPER_WIDTH}), ("default", default),
            ("smoke", load_params(REPO / "params.yaml", {"scale": "smoke"})["tool_train"])]
    if args.small:
        rows, args.steps = rows[-1:], 2
    for scale, tt in rows:
        spec = ("full", tt["depth"], tt["image_size"], tt["batch_size"], tt["gam_channel_gate"], tt["width"], args.steps)
        rates = {}
        for mode in ("native", "portable"):
            with ctx.Pool(1) as pool:              # a new process per mode
                rates[mode], active = pool.map(_throughput, [(mode, *spec)])[0]
        print(f"{scale:8s} {tt['width']:5d} {rates['native']:15.0f} {rates['portable']:17.0f} "
              f"{rates['portable'] / rates['native']:18.2f}")
    print(f"portable kernels in force: {active}")


if __name__ == "__main__":
    main()
