"""The tool study's part of the compute estimate `snakemake -n` prints (pipeline/estimate.py): the
training runs' modelled floating-point operations, and each run's measured time in the last build.

Modelled FLOPs of a run = epochs x (3 x forward FLOPs x training pairs + forward FLOPs x validation
pairs) + forward FLOPs x test pairs. Forward FLOPs per frame pair are counted on the real model
(torch's FlopCounterMode on the meta device: nothing is allocated, so ResNet-101 at 224 px costs a
second, not gigabytes). Epochs are `tool_train.max_epochs` (early stopping only shortens a run: an
upper estimate). Pairs come from the dataset when it exists (results/<build>/<scene>/data/
samples.parquet), else from the simulator's session plan; the splits take `tool_split.fractions`."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Callable

from tactilepipe.core.durations import hours_text as _fmt_h
from tactilepipe.core.simulated import is_simulated
from tactilepipe.core import sourcecache
from tactilepipe.tool.model.variants import NAMED_ARCHITECTURES, Architecture

FLOPS_CACHE = "forward-flops"


@lru_cache(maxsize=None)
def forward_flops(variant: str, depth: int, image_size: int, gam_channel_gate: str, width: int,
                  architecture: Architecture | None = None) -> float:
    """FLOPs (multiply and add counted as two) of one frame pair through the model, inference mode
    (``architecture``: the variant's, as build_model takes it). Counting imports torch (about 6 s on
    2 cores), so each count is kept for the exact source it came from (sourcecache): a dry run that
    plans training does not pay it again."""
    arch = architecture or NAMED_ARCHITECTURES.get(variant)
    built = f"{arch.as_dict()}" if arch else variant
    key = f"{built} depth={depth} size={image_size} gate={gam_channel_gate} width={width}"
    stored = sourcecache.read(FLOPS_CACHE)
    if key not in stored:
        stored = {**stored, key: _count_forward_flops(variant, depth, image_size, gam_channel_gate, width, arch)}
        sourcecache.write(FLOPS_CACHE, stored)
    return float(stored[key])


def _count_forward_flops(variant: str, depth: int, image_size: int, gam_channel_gate: str, width: int,
                         architecture: Architecture | None = None) -> float:
    import torch
    from torch.utils.flop_counter import FlopCounterMode

    from tactilepipe.tool.model.network import build_model
    with torch.device("meta"):
        model = build_model(variant, depth, image_size, gam_channel_gate, width, architecture).eval()
        x = torch.empty(1, 4, image_size, image_size)
        with FlopCounterMode(display=False) as counter:
            model(x)
    return float(counter.get_total_flops())


def planned_pairs(p: dict, scene: str, build_dir: Path) -> int | None:
    """Frame pairs of a tool scene's dataset (``build_dir``: results/<build>/): counted when built,
    else planned by the simulator."""
    samples = build_dir / scene / "data" / "samples.parquet"
    if samples.exists():
        import pyarrow.parquet as pq
        return pq.ParquetFile(samples).metadata.num_rows
    from tactilepipe.tool.scenes import scene_label
    kind = scene_label(scene)
    sessions = p["tool_sessions"]
    if not sessions or not all(is_simulated(s) for s in sessions):
        return None                                 # real recordings not yet ingested: unknown
    from tactilepipe.tool.data.dataset import pair_step
    from tactilepipe.tool.sim import frames_per_trial, session_plan
    step = pair_step(1e9 / p["simulate_tool"]["camera"]["fps"], p["tool_sync"]["pair_rate_hz"])
    pairs_per_trial = -(-frames_per_trial(p, kind) // step)          # every step-th pair, from the first
    per_session = sum(1 for t in session_plan(p) if t.kind == kind) * pairs_per_trial
    return per_session * len(sessions)


def training_flops(p: dict, pairs: int, variant: str, depth: int, image_size: int) -> dict:
    """Modelled FLOPs of one training run (see the module docstring)."""
    tt = p["tool_train"]
    f_train, f_val, f_test = p["tool_split"]["fractions"]
    n_train, n_val, n_test = pairs * f_train, pairs * f_val, pairs * f_test
    if tt["max_train_batches_per_epoch"]:
        n_train = min(n_train, tt["max_train_batches_per_epoch"] * tt["batch_size"])
    fwd = forward_flops(variant, depth, image_size, tt["gam_channel_gate"], tt["width"],
                        Architecture.from_dict(p["tool_variants"][variant]))
    epochs = tt["max_epochs"]
    total = epochs * (3 * fwd * n_train + fwd * n_val) + fwd * n_test
    return {"forward_gflop": fwd / 1e9, "epochs": epochs, "train_pairs": int(n_train), "flop": total}


def measured_seconds(p: dict, rule: str, w: dict, runtimes: Callable[[str], dict]) -> float | None:
    """A training job's train_s in the last build (``runtimes(scene)``: its runtime.json)."""
    return runtimes(w["scene"]).get(w["run"], {}).get("train_s") if rule == "tool_train" else None


def modelled_report(p: dict, jobs: list, run_spec: Callable | None, build_dir: Path) -> list[str]:
    """Lines: each training run's modelled FLOPs and hours, and a warning for runs above their limit."""
    cm = p["resources"]["cost_model"]
    train = [j for j in jobs if j[0] == "tool_train"]
    lines: list[str] = []
    if train and run_spec is not None:
        lines += ["", "Modelled training (tool_train; epochs = max_epochs, early stopping ends sooner):",
                  f"{'scene':<12} {'run':<24} {'variant':<8} {'depth':>5} {'px':>4} {'pairs':>7} "
                  f"{'GFLOP/pair':>10} {'PFLOP':>8} {'on 1 GPU':>10} {'CPU core-h':>11}  device"]
        tot_gpu_h = tot_core_h = 0.0
        over_limit = []
        for _, w, r, threads in train:
            variant, _split, depth, size = run_spec(w["run"])
            pairs = planned_pairs(p, w["scene"], build_dir)
            if pairs is None:
                lines.append(f"{w['scene']:<12} {w['run']:<24} {variant:<8} {depth:>5} {size:>4}   (pairs unknown "
                             "until the real recordings are ingested)")
                continue
            t = training_flops(p, pairs, variant, depth, size)
            gpu_h = t["flop"] / (cm["gpu_tflops"] * 1e12) / 3600
            core_h = t["flop"] / (cm["cpu_gflops_per_core"] * 1e9) / 3600
            tot_gpu_h += gpu_h
            tot_core_h += core_h
            on_gpu = r.get("gpu", 0) > 0
            wall_h = gpu_h if on_gpu else core_h / max(threads, 1)
            if wall_h * 60 > r.get("runtime", float("inf")):
                over_limit.append(f"{w['scene']}/{w['run']} ({_fmt_h(wall_h)} > limit {_fmt_h(r['runtime'] / 60)})")
            lines.append(f"{w['scene']:<12} {w['run']:<24} {variant:<8} {depth:>5} {size:>4} {pairs:>7,} "
                         f"{t['forward_gflop']:>10.2f} {t['flop'] / 1e15:>8.1f} {_fmt_h(gpu_h):>10} "
                         f"{core_h:>11,.1f}  {'GPU' if on_gpu else 'CPU'}")
        lines.append(f"{'total':<12} {'':<24} {'':<8} {'':>5} {'':>4} {'':>7} {'':>10} {'':>8} "
                     f"{_fmt_h(tot_gpu_h):>10} {tot_core_h:>11,.1f}")
        if over_limit:
            lines.append("warning: modelled time above the job's time limit (raise resources.rules.tool_train."
                         "runtime or lower max_epochs): " + ", ".join(over_limit))
    return lines
