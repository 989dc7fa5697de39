"""The Snakemake process's own CPU use while jobs run, with the project's profile against Snakemake's
default job-rate setting, side by side.

A synthetic workflow in a temporary folder stands for the training phase of `make run`: many
ready jobs, two running at a time (`--cores 2`, one thread each), each with the input list of a
real training job (the tool-train stage's source files, its run's parameter stamp, the data set's four
files and a split file) and a body that only sleeps, so all CPU time the Snakemake process spends
is the scheduler's. Its CPU seconds (user + system, /proc/<pid>/stat) are read over a window from the first job's
start, while the other jobs wait ready, and divided by the wall time; then the run is stopped.
Target: under 5 % of a core.

Snakemake's default `--max-jobs-per-timespan 100/1s` makes it re-evaluate the ready jobs every
second, checking the size of every input of each; the project's profile
(workflow/profiles/default/config.yaml) sets a longer timespan, so it re-evaluates when a job ends.

Usage: python benchmarks/bench_scheduler.py [--jobs 76] [--seconds 20] [--window 30] [--small]
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tactilepipe.pipeline import codedeps

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
PROFILE = REPO / "workflow/profiles/default"
TARGET = 0.05
TICKS = os.sysconf("SC_CLK_TCK")

SNAKEFILE = """
from tactilepipe.core.config import load_params
from tactilepipe.tool import runs as run_names

TT = load_params({params!r})["tool_train"]
CODE = {code!r}
DATA = ["data/frames.npy", "data/references.npy", "data/samples.parquet", "data/qc.json"]
JOBS = {jobs!r}

rule all:
    input: [f"out/{{scene}}/{{run}}.done" for scene, run in JOBS]

# as the project's tool_train: its run's spec evaluated from the run name (its split), its own
# parameter stamp, its declared resources
rule train:
    input:
        data=DATA,
        split=lambda w: f"splits/{{run_names.run_spec(TT, w.run)[1]}}.json",
        code=CODE,
        params="params/tool-train/{{run}}.json",
    output: "out/{{scene}}/{{run}}.done"
    params: spec=lambda w: run_names.run_spec(TT, w.run)
    threads: 1
    resources: mem_mb=2000, runtime=60
    shell: "touch started/{{wildcards.scene}}-{{wildcards.run}} && sleep {seconds} && touch {{output}}"
"""


def training_jobs(n: int) -> list[tuple[str, str]]:
    """The first ``n`` (scene, run) training jobs of the default scale (4 tools per scene)."""
    from tactilepipe.core.config import load_params
    from tactilepipe.tool import runs as run_names
    p = load_params(REPO / "params.yaml", {"scale": "default"})
    runs = run_names.tool_runs(p["tool_train"], p["tool_split"]["repeats"], ["t1", "t2", "t3", "t4"])
    jobs = [(scene, run) for scene in ("tool_normal", "tool_shear") for run in runs]
    return (jobs * (n // len(jobs) + 1))[:n] if n > len(jobs) else jobs[:n]


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS         # utime + stime


def make_workflow(wd: Path, jobs: list[tuple[str, str]], seconds: float) -> int:
    (wd / "src").symlink_to(REPO / "src")                      # the code inputs, as the rules list them
    code = codedeps.stage_files("tool-train", REPO)
    for folder in ("data", "splits", "params", "started"):
        (wd / folder).mkdir()
    for name in ("frames.npy", "references.npy", "samples.parquet", "qc.json"):
        (wd / "data" / name).write_bytes(os.urandom(1 << 16))
    from tactilepipe.core.config import load_params
    from tactilepipe.tool import runs as run_names
    tt = load_params(REPO / "params.yaml", {"scale": "default"})["tool_train"]
    (wd / "params" / "tool-train").mkdir()
    for _, run in jobs:
        (wd / "splits" / f"{run_names.run_spec(tt, run)[1]}.json").write_text("{}")
        (wd / "params" / "tool-train" / f"{run}.json").write_text("{}")      # a run's stamp: read for its time only
    (wd / "Snakefile").write_text(SNAKEFILE.format(params=str(REPO / "params.yaml"), code=code, jobs=jobs,
                                                   seconds=seconds))
    return len(code) + 6


def scheduler_share(wd: Path, jobs: int, window: float, extra: list[str]) -> tuple[float, float, float]:
    """(CPU seconds, wall seconds, share of a core) of the Snakemake process from the first job's
    start, for ``window`` seconds or until the last job starts."""
    for folder in ("out", "started"):
        shutil.rmtree(wd / folder, ignore_errors=True)
    (wd / "started").mkdir()
    shutil.rmtree(wd / ".snakemake", ignore_errors=True)
    cmd = [str(BIN / "snakemake"), "--workflow-profile", str(PROFILE), "--cores", "2", "--quiet", "all", *extra]
    env = {**os.environ, "PYTHONPATH": str(REPO / "src")}
    # its own process group, so the run and its sleeping jobs are stopped together when measured
    proc = subprocess.Popen(cmd, cwd=wd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    started = wd / "started"
    try:
        while not any(started.iterdir()):
            if proc.poll() is not None:
                raise SystemExit(f"snakemake ended before a job started: {proc.stderr.read()[-2000:]}")
            time.sleep(0.05)
        cpu0, t0 = cpu_seconds(proc.pid), time.perf_counter()
        while len(list(started.iterdir())) < jobs and proc.poll() is None and time.perf_counter() - t0 < window:
            time.sleep(0.05)
        cpu1, t1 = cpu_seconds(proc.pid), time.perf_counter()
    finally:
        # the rest of the jobs would only sleep; Snakemake's own SIGTERM handling waits for its
        # running jobs and may start more, so the whole group is killed
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        err = proc.communicate()[1]
    if proc.returncode not in (0, -signal.SIGKILL):
        raise SystemExit(f"snakemake failed ({proc.returncode}): {err[-2000:]}")
    return cpu1 - cpu0, t1 - t0, (cpu1 - cpu0) / (t1 - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=76, help="training-like jobs (as at the default scale)")
    ap.add_argument("--seconds", type=float, default=20.0, help="each job's run time")
    ap.add_argument("--window", type=float, default=30.0, help="seconds measured from the first job's start")
    ap.add_argument("--small", action="store_true", help="8 jobs of 2 s, 4 s measured: a check that it runs")
    args = ap.parse_args()
    if args.small:
        args.jobs, args.seconds, args.window = 8, 2.0, 4.0
    with tempfile.TemporaryDirectory(prefix="tactilepipe-bench-scheduler-") as tmp:
        wd = Path(tmp)
        jobs = training_jobs(args.jobs)
        n_inputs = make_workflow(wd, jobs, args.seconds)
        print(f"{len(jobs)} training jobs of the default scale, each sleeping {args.seconds:g} s, 2 at a time, "
              f"{n_inputs} inputs each (the tool-train stage's); Snakemake's CPU over {args.window:g} s from the "
              f"first job's start")
        print(f"{'setting':<52}{'CPU s':>8}{'wall s':>8}{'share of a core':>17}")
        for name, extra in (("Snakemake's default: --max-jobs-per-timespan 100/1s", ["--max-jobs-per-timespan", "100/1s"]),
                            ("the project's profile (workflow/profiles/default)", [])):
            cpu, wall, share = scheduler_share(wd, len(jobs), args.window, extra)
            print(f"{name:<52}{cpu:>8.2f}{wall:>8.1f}{share:>16.1%}")
        print(f"target: under {TARGET:.0%} of a core with the project's profile: "
              f"{'met' if share < TARGET else 'NOT met'}")


if __name__ == "__main__":
    main()
