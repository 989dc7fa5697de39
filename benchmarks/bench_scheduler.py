"""The Snakemake process's own CPU use while jobs run, and how long it lingers after its last job,
with the project's set-up against Snakemake's default job-rate setting, side by side.

A synthetic workflow in a temporary folder stands for the training phase of `make run`: many
ready jobs, two running at a time (`--cores 2`, one thread each), each with the input list of a
real training job (the tool-train stage's source files, its run's parameter stamp, the data set's four
files and a split file) and a body that only sleeps, so all CPU time the Snakemake process spends
is the scheduler's. Every job runs to its end. The CPU seconds of the Snakemake process (user +
system, /proc/<pid>/stat) are read over the second half of the jobs (from the start of the middle
one to the start of the last: by then many jobs have ended while others wait ready), divided by
that wall time; and the time from the last job's end to the process's exit is read as well.

Each scheduling pass that finds jobs waiting arms a timer of `--max-jobs-per-timespan`'s
timespan, and a pass a timer triggers arms the next: so every job that ends while others wait adds
a re-evaluation per timespan, each checking the size of every input of every ready job. At
Snakemake's default (100/1s) they add up to dozens a second; at a long timespan they are rare, but
Snakemake waits for the last plain timer before it exits. The project's set-up
(workflow/profiles/default/config.yaml, 10000/10m, with workflow/rules/scheduler.smk's daemon
timers) needs neither. Target: under 5 % of a core, and an exit within seconds of the last job.

Usage: python benchmarks/bench_scheduler.py [--jobs 76] [--seconds 3] [--small]
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
EXIT_TARGET_S = 5.0
DAEMON_TIMERS = REPO / "workflow/rules/scheduler.smk"
TICKS = os.sysconf("SC_CLK_TCK")

SNAKEFILE = """
{include}
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
    for name, include in (("Snakefile", ""), ("Snakefile.daemon", f"include: {str(DAEMON_TIMERS)!r}")):
        (wd / name).write_text(SNAKEFILE.format(include=include, params=str(REPO / "params.yaml"), code=code,
                                                jobs=jobs, seconds=seconds))
    return len(code) + 6


def scheduler_share(wd: Path, jobs: int, extra: list[str]) -> tuple[float, float, float, float]:
    """(CPU seconds, wall seconds, share of a core) of the Snakemake process over the second half
    of the jobs (from the middle job's start to the last one's), and the seconds from the last
    job's end to the process's exit."""
    for folder in ("out", "started"):
        shutil.rmtree(wd / folder, ignore_errors=True)
    (wd / "started").mkdir()
    shutil.rmtree(wd / ".snakemake", ignore_errors=True)
    cmd = [str(BIN / "snakemake"), "--workflow-profile", str(PROFILE), "--cores", "2", "--quiet", "all", *extra]
    env = {**os.environ, "PYTHONPATH": str(REPO / "src")}
    proc = subprocess.Popen(cmd, cwd=wd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    started, out = wd / "started", wd / "out"

    def wait_for(folder: Path, n: int) -> None:
        """Until ``folder`` holds ``n`` files (a job's start mark, or its output one folder down)."""
        while sum(p.is_file() for p in folder.rglob("*")) < n:
            if proc.poll() is not None:
                raise SystemExit(f"snakemake ended early ({proc.returncode}): {proc.stderr.read()[-2000:]}")
            time.sleep(0.02)
    try:
        wait_for(started, jobs // 2)
        cpu0, t0 = cpu_seconds(proc.pid), time.perf_counter()
        wait_for(started, jobs)
        cpu1, t1 = cpu_seconds(proc.pid), time.perf_counter()
        wait_for(out, jobs)
        last = time.perf_counter()
        err = proc.communicate(timeout=900)[1]
        lingered = time.perf_counter() - last
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    if proc.returncode != 0:
        raise SystemExit(f"snakemake failed ({proc.returncode}): {err[-2000:]}")
    return cpu1 - cpu0, t1 - t0, (cpu1 - cpu0) / (t1 - t0), lingered


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=76, help="training-like jobs (as at the default scale)")
    ap.add_argument("--seconds", type=float, default=3.0, help="each job's run time")
    ap.add_argument("--small", action="store_true",
                    help="12 jobs of 1 s, without the one-minute setting: a check that it runs")
    args = ap.parse_args()
    if args.small:
        args.jobs, args.seconds = 12, 1.0
    settings = [("Snakemake's default: --max-jobs-per-timespan 100/1s", "Snakefile", ["--max-jobs-per-timespan", "100/1s"]),
                ("1000/60s, plain timers (the profile before)", "Snakefile", ["--max-jobs-per-timespan", "1000/60s"]),
                ("the project's: profile + daemon timers", "Snakefile.daemon", [])]
    if args.small:
        del settings[1]
    with tempfile.TemporaryDirectory(prefix="tactilepipe-bench-scheduler-") as tmp:
        wd = Path(tmp)
        jobs = training_jobs(args.jobs)
        n_inputs = make_workflow(wd, jobs, args.seconds)
        print(f"{len(jobs)} training jobs of the default scale, each sleeping {args.seconds:g} s, 2 at a time, "
              f"{n_inputs} inputs each (the tool-train stage's); Snakemake's CPU over the second half of the jobs, "
              f"and its exit after the last")
        print(f"{'setting':<54}{'CPU s':>8}{'wall s':>8}{'share of a core':>17}{'exit after last job, s':>24}")
        for name, snakefile, extra in settings:
            cpu, wall, share, lingered = scheduler_share(wd, len(jobs), ["-s", snakefile, *extra])
            print(f"{name:<54}{cpu:>8.2f}{wall:>8.1f}{share:>16.1%}{lingered:>24.1f}")
        print(f"target: under {TARGET:.0%} of a core and an exit within {EXIT_TARGET_S:g} s with the project's set-up: "
              f"{'met' if share < TARGET and lingered < EXIT_TARGET_S else 'NOT met'}")


if __name__ == "__main__":
    main()
