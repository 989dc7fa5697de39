"""What every stage shares: its parameters (the only way in) and parallel jobs."""

from __future__ import annotations

import json
import sys

from tactilepipe.core.errors import ConfigError


def param_overrides(args) -> dict:
    """``--override`` (a JSON object; how Snakemake hands --config on) plus ``--scale``."""
    try:
        overrides = json.loads(args.override) if args.override else {}
    except json.JSONDecodeError as exc:
        raise ConfigError(f"--override is not valid JSON: {exc}") from None
    if not isinstance(overrides, dict):
        raise ConfigError(f"--override must be a JSON object, got {type(overrides).__name__}")
    if args.scale:
        overrides["scale"] = args.scale
    return overrides


def stage_params(args, *keys: str) -> dict:
    """The stage's parameters: params.yaml (+ --override), resolved for the scale, cut down to
    ``keys`` (dotted, e.g. "tool_train.lr": the ``params`` of its declaration). These keys are the
    stage's only way in: reading any other key raises, and the workflow stamps the same keys
    (codedeps.stage_param_keys) to decide what a parameter change re-runs."""
    from tactilepipe.core.config import declared, load_params
    return declared(load_params(args.params, param_overrides(args)), keys, f"tactilepipe {args.command}")


def _progress(iterable, desc: str, total: int | None = None):
    from tqdm import tqdm
    return tqdm(iterable, desc=desc, total=total, unit="bag", file=sys.stderr,
                disable=None, mininterval=1.0)


def _call(job):
    func, *args = job
    func(*args)


def run_parallel(jobs: list, workers: int, desc: str) -> None:
    """Run (func, *args) jobs on ``workers`` processes, with a progress bar; errors propagate."""
    if workers <= 1:
        for job in _progress(jobs, desc):
            _call(job)
        return
    from concurrent.futures import ProcessPoolExecutor
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for _ in _progress(pool.map(_call, jobs), desc, total=len(jobs)):
            pass
