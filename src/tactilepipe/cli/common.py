"""What every stage shares: its parameters (the only way in) and parallel jobs."""

from __future__ import annotations

import json
import sys
import time

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


def stage_params(args, *keys: str, checks=()) -> dict:
    """The stage's parameters, cut down to ``keys`` (dotted, e.g. "tool_train.lr": the ``params`` of
    its declaration): reading any other key raises. Under the workflow they come from the stage's
    stamp (``--stamp results/<build>/params/<stage>.json``), the values Snakemake validated (every
    study's checks) and records, so a job receives exactly what its stamp says; by hand, from
    params.yaml (+ --override), resolved for the scale and passed through ``checks``, its study's
    checks (the ``checks=`` of its declaration): not the other studies', so that one study's checks
    are no code of another study's stages."""
    from tactilepipe.core.config import declared, load_params
    from tactilepipe.pipeline.stamps import stamp_values
    where = f"tactilepipe {args.command}"
    if args.stamp:
        if args.override or args.scale:
            raise ConfigError("--stamp holds the stage's resolved values: give it without --override or --scale")
        return declared(stamp_values(args.stamp, args.command), keys, where)
    return declared(load_params(args.params, param_overrides(args), checks), keys, where)


def _progress(iterable, desc: str, total: int | None = None):
    """A bar on a terminal; elsewhere (a job's log under Snakemake) a count line every tenth of
    the jobs and at the end, so a long stage still says how far it is."""
    total = len(iterable) if total is None else total
    if getattr(sys.stderr, "isatty", lambda: False)():
        from tqdm import tqdm
        return tqdm(iterable, desc=desc, total=total, unit="job", file=sys.stderr, mininterval=1.0)
    return _counted(iterable, desc, total)


def _counted(iterable, desc: str, total: int):
    start, every = time.perf_counter(), max(1, total // 10)
    done = 0
    for item in iterable:
        yield item                      # the caller runs (or has run) the job before the next item
        done += 1
        if done % every == 0 or done == total:
            print(f"{desc}: {done}/{total} done ({time.perf_counter() - start:.1f} s)", file=sys.stderr, flush=True)


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
