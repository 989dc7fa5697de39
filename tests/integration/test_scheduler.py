"""Snakemake's own process while a run works and when it ends (the default profile and the
Snakefile; benchmarks/bench_scheduler.py measures the CPU side)."""

from __future__ import annotations

import re
import subprocess
import time
from pathlib import Path

import pytest
import yaml

from support.project import BIN, ENV, REPO, copy_project

pytestmark = pytest.mark.integration

UNITS = {"s": 1, "m": 60, "h": 3600}


def test_a_run_ends_when_its_last_job_does_not_a_timespan_later(tmp_path: Path):
    """Each scheduling pass arms a timer of the profile's timespan (ten minutes, so the scheduler
    sleeps between finished jobs); a plain timer would keep Snakemake alive that long after its
    last job. The Snakefile's daemon timers let it exit: one real job (the smoke drift
    simulation) through the project's workflow and profile ends in well under the timespan."""
    profile = yaml.safe_load((REPO / "workflow/profiles/default/config.yaml").read_text())
    count, span, unit = re.fullmatch(r"(\d+)/(\d+)([smh])", profile["max-jobs-per-timespan"]).groups()
    timespan_s = int(span) * UNITS[unit]
    assert timespan_s >= 300, "a short timespan re-evaluates the ready jobs often (docs/benchmarks.md)"
    wd = copy_project(tmp_path, scale="smoke")
    start = time.monotonic()
    try:
        proc = subprocess.run([str(BIN / "snakemake"), "--cores", "2", "--workflow-profile", "workflow/profiles/default",
                               "raw/drift/sim-smoke/session.json"], cwd=wd, env={**ENV, "PYTHONPATH": str(wd / "src")},
                              capture_output=True, text=True, timeout=timespan_s / 2)
    except subprocess.TimeoutExpired:
        pytest.fail(f"Snakemake still running after {timespan_s / 2:.0f} s: it waits for its scheduler's timers")
    elapsed = time.monotonic() - start
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "1 of 1 steps (100%) done" in proc.stdout + proc.stderr
    assert elapsed < timespan_s / 2
