"""The compute a run needs, printed at the end of `snakemake -n` (workflow/rules/common.smk).

Two numbers per rule:

* booked: what the jobs ask the scheduler for (params.yaml `resources`, overlaid by the scale):
  jobs x threads x time limit (CPU-hours), jobs x GPUs x time limit (GPU-hours), memory per job.
  These are upper limits, not predictions.
* modelled, where a study models its jobs (its contract's ``modelled_report``; the tool study's
  training runs, nearly all of the compute at the paper scale: tool/estimate.py): FLOPs become
  hours through `resources.cost_model`, sustained GFLOP/s per CPU core (measured here) and TFLOP/s
  of one GPU with mixed precision (assumed).
* measured, where the last build of the same build folder left run times (its scenes'
  runtime.json) for a study's timed rules (its contract's ``MEASURED_RULES`` and
  ``measured_seconds``: a training job its run's train_s, a volume MLP or baseline job its
  method's fit_s per fold x folds). The sum is the wall time of those jobs run one after another,
  on that machine; jobs without a record (a new run, a first build) are counted apart, not guessed.
"""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path
from typing import Callable, Iterable

from tactilepipe.core.durations import hours_text as _fmt_h
from tactilepipe.pipeline.layout import results_root
from tactilepipe.studies import contracts

CONTRACTS = contracts()
# (rule, wildcards, resources, threads) of one job, as Snakemake's DAG has it
Job = tuple[str, dict, dict, int]


# the rules whose jobs the last build timed (runtime.json), and the study that reads those times
MEASURED_RULES = {rule: study for study, c in CONTRACTS.items() for rule in c.MEASURED_RULES}


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
    study = MEASURED_RULES.get(rule)
    if study is None:
        return None
    value = CONTRACTS[study].measured_seconds(p, rule, w, lambda scene: last_runtimes(p, scene, root))
    return float(value) if isinstance(value, (int, float)) else None


def measured_report(p: dict, jobs: list["Job"], root: Path = Path(".")) -> list[str]:
    """Lines: the wall time of the jobs the last build has run times for, per rule."""
    by_rule: dict[str, list[float | None]] = defaultdict(list)
    for job in jobs:
        if job[0] in MEASURED_RULES:
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
             "(src/tactilepipe/tool/estimate.py).",
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

    for contract in CONTRACTS.values():
        lines += contract.modelled_report(p, jobs, run_spec, root / results_root(p["build"]))
    lines += measured_report(p, jobs, root)
    return "\n".join(lines)
