"""Training jobs on a 2-core machine: one job on 2 threads against two jobs at once on 1 thread each.

The default scale trains many small models (each variant on every repeated split, leave-one-tool-out
for every tool, the sweep). At 16 px a model's kernels are too small to keep two threads busy, so
two single-thread jobs side by side should finish more work per second than one job on both cores.
This prints both, side by side, as frame pairs per second of training (forward, backward and Adam
step on random data at the default scale's input size, batch and depth), and their ratio: the
setting behind ``tool_train.num_threads: 1`` (Snakemake then runs two training jobs with --cores 2).

Usage: python benchmarks/bench_train_jobs.py [--variant full] [--steps 40]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import time
from pathlib import Path

from tactilepipe.core.config import load_params
from tactilepipe.tool.model.train import train_throughput

REPO = Path(__file__).resolve().parents[1]


def _job(args: tuple) -> float:
    variant, depth, size, batch, steps, threads = args
    return train_throughput(variant, depth, size, batch, steps=steps, num_threads=threads)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", default="full")
    ap.add_argument("--steps", type=int, default=40)
    args = ap.parse_args()
    tt = load_params(REPO / "params.yaml", {"scale": "default"})["tool_train"]
    spec = (args.variant, tt["depth"], tt["image_size"], tt["batch_size"], args.steps)
    ctx = mp.get_context("spawn")
    with ctx.Pool(1) as pool:
        t = time.perf_counter()
        one = pool.map(_job, [spec + (2,)])[0]
        one_wall = time.perf_counter() - t
    with ctx.Pool(2) as pool:
        t = time.perf_counter()
        two = pool.map(_job, [spec + (1,), spec + (1,)])
        two_wall = time.perf_counter() - t
    print(f"{args.variant}, ResNet-{tt['depth']}, {tt['image_size']} px, batch {tt['batch_size']}, {args.steps} steps")
    print(f"{'setting':<40}{'pairs/s':>10}{'wall (s)':>10}")
    print(f"{'one job, 2 threads':<40}{one:>10,.0f}{one_wall:>10.1f}")
    print(f"{'two jobs at once, 1 thread each (sum)':<40}{sum(two):>10,.0f}{two_wall:>10.1f}")
    print(f"two single-thread jobs / one two-thread job: {sum(two) / one:.2f}x")


if __name__ == "__main__":
    main()
