"""The compute a run needs, printed at the end of `snakemake -n` (workflow/rules/common.smk).

Two numbers per rule:

* booked: what the jobs ask the scheduler for (params.yaml `resources`, overlaid by the scale):
  jobs x threads x time limit (CPU-hours), jobs x GPUs x time limit (GPU-hours), memory per job.
  These are upper limits, not predictions.
* modelled, for the training rule (nearly all of the compute at the paper scale): floating-point
  operations of each run = epochs x (3 x forward FLOPs x training pairs + forward FLOPs x
  validation pairs) + forward FLOPs x test pairs. Forward FLOPs per frame pair are counted on the
  real model (torch's FlopCounterMode on the meta device: nothing is allocated, so ResNet-101 at
  224 px costs a second, not gigabytes). Epochs are `tool_train.max_epochs` (early stopping only
  shortens a run: an upper estimate). Pairs come from the dataset when it exists
  (results/<build>/<scene>/data/samples.parquet), else from the simulator's session plan; the splits take
  `tool_split.fractions`. FLOPs become hours through `resources.cost_model`: sustained GFLOP/s per
  CPU core (measured here) and TFLOP/s of one GPU with mixed precision (assumed).
* measured, where the last build of the same build folder left run times (its scenes'
  runtime.json): a training job takes its run's train_s, a volume MLP or baseline job its method's
  fit_s per fold x folds. The sum is the wall time of those jobs run one after another, on that
  machine; jobs without a record (a new run, a first build) are counted apart, not guessed.
"""

from __future__ import annotations

import json
from collections import defaultdict
from functools import lru_cache
from pathlib import Path
from typing import Callable, Iterable

from tactilepipe.pipeline import sourcecache
from tactilepipe.pipeline.layout import results_root
from tactilepipe.core.simulated import is_simulated
from tactilepipe.tool.model.variants import NAMED_ARCHITECTURES, Architecture

# (rule, wildcards, resources, threads) of one job, as Snakemake's DAG has it
Job = tuple[str, dict, dict, int]
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


def planned_pairs(p: dict, scene: str, root: Path = Path(".")) -> int | None:
    """Frame pairs of a tool scene's dataset: counted when built, else planned by the simulator."""
    samples = root / results_root(p["build"]) / scene / "data" / "samples.parquet"
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


def last_runtimes(p: dict, scene: str, root: Path = Path(".")) -> dict[str, dict]:
    """A scene's runtime.json from the last build ({} when there is none or it cannot be read: an
    estimate does without it)."""
    path = root / results_root(p["build"]) / scene / "runtime.json"
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def measured_seconds(p: dict, job: "Job", root: Path = Path(".")) -> float | None:
    """What the job took in the last build (see the module docstring), or None without a record."""
    rule, w = job[0], job[1]
    if rule == "tool_train":
        value = last_runtimes(p, w["scene"], root).get(w["run"], {}).get("train_s")
    elif rule in ("volume_train", "volume_baseline"):
        method = w["modality"] if rule == "volume_train" else "baseline"
        fit_s = last_runtimes(p, "volume", root).get(method, {}).get("fit_s")
        value = None if fit_s is None else fit_s * p["folds"]["n_folds"]
    else:
        return None
    return float(value) if isinstance(value, (int, float)) else None


def measured_report(p: dict, jobs: list["Job"], root: Path = Path(".")) -> list[str]:
    """Lines: the wall time of the jobs the last build has run times for, per rule."""
    by_rule: dict[str, list[float | None]] = defaultdict(list)
    for job in jobs:
        if job[0] in ("tool_train", "volume_train", "volume_baseline"):
            by_rule[job[0]].append(measured_seconds(p, job, root))
    known = {r: [s for s in v if s is not None] for r, v in by_rule.items()}
    if not any(known.values()):
        return ["", "Measured wall time: no run times of a last build "
                f"({results_root(p['build'])}/<scene>/runtime.json) for these jobs."]
    lines = ["", f"Measured wall time (the last build's {results_root(p['build'])}/<scene>/runtime.json):",
             f"{'rule':<20} {'jobs':>5} {'measured':>8} {'wall':>10}  {'per run':>10}"]
    for rule, values in sorted(by_rule.items()):
        got = known[rule]
        mean = _fmt_h(sum(got) / len(got) / 3600) if got else "-"
        lines.append(f"{rule:<20} {len(values):>5} {len(got):>8} {_fmt_h(sum(got) / 3600):>10}  {mean:>10}")
    total = sum(sum(v) for v in known.values())
    missing = sum(len(v) - len(known[r]) for r, v in by_rule.items())
    lines.append(f"{'total':<20} {sum(map(len, by_rule.values())):>5} {sum(map(len, known.values())):>8} "
                 f"{_fmt_h(total / 3600):>10}  (jobs one after another; {missing} without a record not counted)")
    return lines


def _fmt_h(hours: float) -> str:
    if hours < 0.1:
        return f"{hours * 60:.1f} min"
    return f"{hours:,.1f} h"


def estimate_report(p: dict, jobs: Iterable[Job], run_spec: Callable | None = None,
                    root: Path = Path(".")) -> str:
    """The estimate as text: a table per rule, then the modelled training runs."""
    jobs = list(jobs)
    cm = p["resources"]["cost_model"]
    by_rule: dict[str, list[Job]] = defaultdict(list)
    for job in jobs:
        by_rule[job[0]].append(job)

    lines = [f"Compute estimate ({len(jobs)} jobs, scale '{p['scale']}'): booked = what the jobs ask the "
             f"scheduler for (params.yaml resources),",
             "modelled = FLOP count of the model x pairs x epochs at "
             f"{cm['cpu_gflops_per_core']:g} GFLOP/s per CPU core or {cm['gpu_tflops']:g} TFLOP/s per GPU "
             "(src/tactilepipe/pipeline/estimate.py).",
             ""]
    header = f"{'rule':<20} {'jobs':>5} {'cores':>5} {'GPUs':>4} {'mem/job':>8} {'limit/job':>10} " \
             f"{'booked CPU-h':>12} {'booked GPU-h':>12}"
    lines += [header, "-" * len(header)]
    tot_cpu = tot_gpu = 0.0
    for rule, rjobs in sorted(by_rule.items()):
        cpu_h = sum(t * r.get("runtime", 0) / 60 for _, _, r, t in rjobs)
        gpu_h = sum(r.get("gpu", 0) * r.get("runtime", 0) / 60 for _, _, r, _ in rjobs)
        tot_cpu, tot_gpu = tot_cpu + cpu_h, tot_gpu + gpu_h
        mem = max(r.get("mem_mb", 0) for _, _, r, _ in rjobs) / 1000
        limit = max(r.get("runtime", 0) for _, _, r, _ in rjobs) / 60
        threads = max(t for _, _, _, t in rjobs)
        gpus = max(r.get("gpu", 0) for _, _, r, _ in rjobs)
        lines.append(f"{rule:<20} {len(rjobs):>5} {threads:>5} {gpus:>4} {mem:>6.1f}GB {_fmt_h(limit):>10} "
                     f"{cpu_h:>12,.1f} {gpu_h:>12,.1f}")
    lines += ["-" * len(header), f"{'total':<20} {len(jobs):>5} {'':>5} {'':>4} {'':>8} {'':>10} "
              f"{tot_cpu:>12,.1f} {tot_gpu:>12,.1f}"]

    train = by_rule.get("tool_train", [])
    if train and run_spec is not None:
        lines += ["", "Modelled training (tool_train; epochs = max_epochs, early stopping ends sooner):",
                  f"{'scene':<12} {'run':<24} {'variant':<8} {'depth':>5} {'px':>4} {'pairs':>7} "
                  f"{'GFLOP/pair':>10} {'PFLOP':>8} {'on 1 GPU':>10} {'CPU core-h':>11}  device"]
        tot_gpu_h = tot_core_h = 0.0
        over_limit = []
        for _, w, r, threads in train:
            variant, _split, depth, size = run_spec(w["run"])
            pairs = planned_pairs(p, w["scene"], root)
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
    lines += measured_report(p, jobs, root)
    return "\n".join(lines)
