"""Every benchmark runs at its small size (`--small`) and prints its rows, so a change that breaks
one is found by the suite, not at the next `make bench`. The numbers at that size mean nothing;
the script's exit status and its rows do."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest

from support.project import BIN, REPO

pytestmark = [pytest.mark.integration, pytest.mark.slow]

# each script and the rows it must print (regular expressions, each matched in its output)
ROWS = {
    "bench_dvc.py": [r"\| no-op `snakemake` \| [0-9.]+ s \|", r"\| no-op `dvc repro drift` \| [0-9.]+ s \|"],
    "bench_gemm.py": [r"all conv \+ linear layers +[0-9.]+ +[0-9.]+ +[0-9.]+ +[0-9.]+ +[0-9.]+",
                      r"training step \(fwd, bwd, Adam\) +[0-9.]+ +[0-9.]+ +[0-9.]+ +[0-9.]+ +[0-9.]+"],
    "bench_integrators.py": [r"\| exponential \| 500 \| 1 \|", r"\| euler \| 500 \| 2 \|"],
    "bench_kernels.py": [r"smoke +8 +[0-9]+ +[0-9]+ +[0-9.]+", r"portable kernels in force: .*'mode': 'portable'"],
    "bench_label_budget.py": [r"zero offset N +-?[0-9.]+ +[0-9]+ +[0-9]+ +[0-9]+", r"clean +9 +0 +0"],
    "bench_live.py": [r"quiet +[0-9.]+ +[0-9.]+ +[0-9.]+ +[0-9]+ +[0-9.]+"],
    "bench_predict_load.py": [r"params.yaml predict .* +[0-9.]+ +[0-9.]+"],
    "bench_scheduler.py": [r"Snakemake's default: --max-jobs-per-timespan 100/1s +[0-9.]+ +[0-9.]+ +[0-9.]+% +[0-9.]+",
                           r"the project's: profile \+ daemon timers +[0-9.]+ +[0-9.]+ +[0-9.]+% +[0-9.]+",
                           r"target: under 5% of a core and an exit within"],
    "bench_sync.py": [r"within one frame period .*: [0-9.]+%", r"shifted silently: +[0-9.]+%"],
    "bench_tool.py": [r"rendered QVGA frames/s: [0-9,]+", r"ingest / bare = [0-9]+%", r"ours / JPEG loader = [0-9.]+x",
                      r"[0-9]+ pairs, median latency [0-9.]+ ms, sustained [0-9.]+ pairs/s"],
    "bench_train_jobs.py": [r"one job, 2 threads +[0-9,]+ +[0-9.]+", r"two single-thread jobs / one two-thread job: [0-9.]+x"],
    "bench_volume.py": [r"tactilepipe ingest \(decode\+validate\+Parquet\) +[0-9.]+ +[0-9,]+", r"ingest / bare = [0-9]+%"],
}


def test_every_benchmark_has_its_small_run_here():
    assert sorted(p.name for p in (REPO / "benchmarks").glob("*.py")) == sorted(ROWS)


# bench_dvc's small run is a git + DVC project building the drift scene, some 3 minutes: the DVC
# workflow test covers those commands in make test
EXTENDED = {"bench_dvc.py"}


@pytest.mark.parametrize("script", [pytest.param(s, marks=pytest.mark.extended) if s in EXTENDED else s
                                    for s in sorted(ROWS)])
def test_the_benchmark_runs_at_its_small_size(script: str, tmp_path):
    env = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}", "PYTHONPATH": str(REPO / "src")}
    proc = subprocess.run([sys.executable, str(REPO / "benchmarks" / script), "--small"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, f"{script} --small failed ({proc.returncode}):\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
    missing = [row for row in ROWS[script] if not re.search(row, proc.stdout)]
    assert not missing, f"{script} --small printed no row matching {missing}:\n{proc.stdout[-3000:]}"
