"""Volume-scene benchmarks, printed side by side in one run.

1. Bag ingest (bag -> validated Parquet shard) in messages/s against a bare rosbags read loop
   (Reader + deserialize_ros1 of every message) over the same bags. Target: >= 50 % of it.
2. Wall time of the whole volume scene at default scale with `snakemake --cores 2`, in a scratch
   copy of the workflow: from nothing (simulation included) and from existing recordings.
   Target: <= 3 min on 2 cores.

Usage: python benchmarks/bench_volume.py [--bags N] [--scale default] [--skip-scene] [--small]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from rosbags.rosbag1 import Reader

from tactilepipe.core.config import load_params
from tactilepipe.papillarray.messages import typestore
from tactilepipe.papillarray.shards import ingest_bag
from tactilepipe.volume.simulate import session_plan, write_lift_bag

REPO = Path(__file__).resolve().parents[1]


def bare_read(bags: list[Path]) -> int:
    store = typestore()
    n = 0
    for bag in bags:
        with Reader(bag) as reader:
            for conn, _, raw in reader.messages():
                store.deserialize_ros1(raw, conn.msgtype)
                n += 1
    return n


def ingest_all(bags: list[Path], out: Path) -> int:
    return sum(ingest_bag(bag, out / f"{bag.stem}.parquet")["messages"] for bag in bags)


def best_of(repeats: int, func, *args) -> tuple[float, int]:
    times, count = [], 0
    for _ in range(repeats):
        t0 = time.perf_counter()
        count = func(*args)
        times.append(time.perf_counter() - t0)
    return min(times), count


def bench_ingest(n_bags: int, scale: str, work: Path) -> None:
    p = load_params(REPO / "params.yaml", {"scale": scale})
    plan = session_plan(p["simulate_volume"])[:: max(1, len(session_plan(p["simulate_volume"])) // n_bags)][:n_bags]
    bags = []
    for lift in plan:
        bag = work / "bags" / f"{lift.name}.bag"
        write_lift_bag(bag, lift, p["simulate_volume"], p["seed"])
        bags.append(bag)
    (work / "shards").mkdir()
    t_bare, n_bare = best_of(3, bare_read, bags)
    t_ours, n_ours = best_of(3, ingest_all, bags, work / "shards")
    assert n_bare == n_ours, (n_bare, n_ours)
    rate_bare, rate_ours = n_bare / t_bare, n_ours / t_ours
    print(f"\n== Ingest: {len(bags)} bags, {n_bare} messages, {p['simulate_volume']['rate_hz']} Hz, best of 3")
    print(f"{'reader':<44}{'seconds':>10}{'messages/s':>14}")
    print(f"{'bare rosbags loop (read + deserialize)':<44}{t_bare:>10.2f}{rate_bare:>14,.0f}")
    print(f"{'tactilepipe ingest (decode+validate+Parquet)':<44}{t_ours:>10.2f}{rate_ours:>14,.0f}")
    ratio = rate_ours / rate_bare
    print(f"ingest / bare = {ratio:.0%}  (target >= 50 %: {'met' if ratio >= 0.5 else 'NOT met'})")


def run_scene(workdir: Path, scale: str) -> float:
    cmd = [sys.executable, "-m", "snakemake", "--cores", "2", "--quiet", "all",
           "--config", f"scale={scale}", "scenes=[volume]"]
    t0 = time.perf_counter()
    # the copy runs its own code: the Snakefile stops when the package it imports is another tree's
    env = {**os.environ, "PYTHONPATH": str(workdir / "src")}
    subprocess.run(cmd, cwd=workdir, env=env, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def bench_scene(scale: str, work: Path) -> None:
    wd = work / "scene"
    wd.mkdir()
    for name in ("Snakefile", "params.yaml"):
        shutil.copy(REPO / name, wd / name)
    for name in ("workflow", "src", "studies"):
        shutil.copytree(REPO / name, wd / name, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info", "raw",
                                                                              "results", "cache", "tmp"))
    full = run_scene(wd, scale)
    shutil.rmtree(wd / "results")
    from_raw = run_scene(wd, scale)
    print(f"\n== Volume scene at scale '{scale}', snakemake --cores 2")
    print(f"{'run':<44}{'wall s':>10}{'target':>14}")
    print(f"{'from nothing (simulate + ingest + fit + report)':<44}{full:>10.1f}{'<= 180 s':>14}")
    print(f"{'from recordings (ingest + fit + report)':<44}{from_raw:>10.1f}{'<= 180 s':>14}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bags", type=int, default=20)
    ap.add_argument("--scale", default="default")
    ap.add_argument("--skip-scene", action="store_true")
    ap.add_argument("--small", action="store_true", help="2 smoke-scale bags, no scene: a check that it runs")
    args = ap.parse_args()
    if args.small:
        args.bags, args.scale, args.skip_scene = 2, "smoke", True
    with tempfile.TemporaryDirectory(prefix="tactilepipe-bench-") as tmp:
        bench_ingest(args.bags, args.scale, Path(tmp))
        if not args.skip_scene:
            bench_scene(args.scale, Path(tmp))


if __name__ == "__main__":
    main()
