"""Training jobs on a 2-core machine: one job on 2 threads against two jobs at once on 1 thread each.

The default scale trains many small models (each variant on every repeated split, leave-one-tool-out
for every tool, the sweep). At 16 px a model's kernels are too small to keep two threads busy, so
two single-thread jobs side by side should finish more work per second than one job on both cores.
This prints both, side by side, as frame pairs per second of training (forward, backward and Adam
step on random data at the default scale's input size, batch and depth), and their ratio: the
setting behind ``tool_train.num_threads: 1`` (Snakemake then runs two training jobs with --cores 2).

Usage: python benchmarks/bench_train_jobs.py [--variant full] [--steps 40] [--small]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import time
from pathlib import Path

from tactilepipe.core.config import load_params
import torch
from torch import nn

from tactilepipe.tool.model.network import build_model
from tactilepipe.tool.model.train import make_optimizer, to_input

REPO = Path(__file__).resolve().parents[1]


def train_throughput(variant: str, depth: int, image_size: int, batch_size: int, gam_channel_gate: str, width: int,
                     steps: int = 3, channels_last: bool = True, num_threads: int | None = None,
                     seed: int = 0) -> float:
    """Training speed in frame pairs per second (forward + backward + Adam step on random CPU
    data, after one warm-up step): what an epoch will cost on this machine."""
    saved = torch.get_num_threads()
    try:
        if num_threads:
            torch.set_num_threads(num_threads)
        torch.manual_seed(seed)
        model = build_model(variant, depth, image_size, gam_channel_gate, width)
        if channels_last:
            model = model.to(memory_format=torch.channels_last)
        opt = make_optimizer(model, 2e-4)
        x = to_input(torch.rand(batch_size, 4, image_size, image_size), torch.device("cpu"), channels_last)
        y = torch.rand(batch_size)
        model.train()

        def step():
            opt.zero_grad(set_to_none=True)
            nn.functional.l1_loss(model(x), y).backward()
            opt.step()

        step()
        t = time.perf_counter()
        for _ in range(steps):
            step()
        return batch_size * steps / (time.perf_counter() - t)
    finally:
        torch.set_num_threads(saved)


def _job(args: tuple) -> float:
    variant, depth, size, batch, gate, width, steps, threads = args
    return train_throughput(variant, depth, size, batch, gate, width, steps=steps, num_threads=threads)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", default="full")
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--small", action="store_true", help="2 steps at the smoke scale: a check that it runs")
    args = ap.parse_args()
    if args.small:
        args.steps = 2
    tt = load_params(REPO / "params.yaml", {"scale": "smoke" if args.small else "default"})["tool_train"]
    spec = (args.variant, tt["depth"], tt["image_size"], tt["batch_size"], tt["gam_channel_gate"], tt["width"], args.steps)
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
