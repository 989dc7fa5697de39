"""Every file a stage reads is a declared input (the file-read audit, tests/support/read_audit.py).

The shared smoke build runs under strace, which records every file each stage process opens, and
with every stage's imports recorded. Each stage's reads must be its rule's inputs (or outputs), and
its modules its rule's code. Real-session layouts (a native rig session with nano17.cal and
meta.json, the public layout with trials.csv, ROS bags with sidecars, a drift session with
session.json) go through the same audit in a project of their own. Removing an input from a rule
makes the audit fail, naming the rule and the file."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from support.project import BIN, SMOKE, copy_project, results, run
from support.read_audit import Audit, audited_snakemake, declared_jobs, strace_available, undeclared, undeclared_code

pytestmark = pytest.mark.integration

SNAKEMAKE = [str(BIN / "snakemake"), "--cores", "2"]


def _require_strace() -> None:
    if not strace_available():
        if os.environ.get("CI"):
            pytest.fail("strace is missing: .ci/run installs it for the file-read audit")
        pytest.skip("strace is not installed (apt-get install strace): the file-read audit needs it")


def _smoke_audit(build: Path) -> Audit:
    return Audit(build, build.parent / f"{build.name}.strace", build.parent / f"{build.name}.imports")


def test_every_stage_of_the_smoke_build_reads_only_declared_files(smoke_build: Path):
    _require_strace()
    audit, jobs = _smoke_audit(smoke_build), declared_jobs(smoke_build, SNAKEMAKE)
    reads, imports = audit.reads(), audit.imported()
    assert len(jobs) > 100 and all(j.command in reads and j.command in imports for j in jobs), \
        [j.rule for j in jobs if j.command not in reads or j.command not in imports][:5]
    assert {j.rule for j in jobs} >= {"volume_simulate", "papillarray_ingest", "volume_dataset", "volume_train",
                                      "volume_report", "drift_simulate", "drift_report", "tool_simulate",
                                      "tool_ingest", "tool_dataset", "tool_split", "tool_train", "tool_model_report",
                                      "tool_data_report", "tool_clock_figure"}
    assert sum(len(files) for files in reads.values()) > 5000          # frames, bags, shards, data sets
    assert undeclared(reads, jobs) == {}
    assert undeclared_code(imports, jobs) == {}


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text, (path, old)
    path.unlink()                                   # a hard link: write a file of its own
    path.write_text(text.replace(old, new))


def test_the_audit_names_a_read_whose_input_a_rule_no_longer_declares(smoke_build: Path, tmp_path: Path):
    _require_strace()
    wd = tmp_path / "project"
    shutil.copytree(smoke_build, wd, copy_function=os.link, symlinks=True)
    _edit(wd / "workflow/rules/drift.smk", '        raw=session_files("drift"),\n', "")
    _edit(wd / "src/tactilepipe/tool/contract.py",
          'return [f"{folder}/{CALIBRATION}", f"{recording.path}/meta.json"]', 'return [f"{recording.path}/meta.json"]')
    problems = undeclared(_smoke_audit(smoke_build).reads(), declared_jobs(wd, SNAKEMAKE))
    drift = [files for job, files in problems.items() if job.startswith("drift_report:")]
    assert drift and "raw/drift/sim-smoke/loaded_t05.bag" in drift[0], problems.keys()
    ingest = {job: files for job, files in problems.items() if job.startswith("tool_ingest:")}
    assert len(ingest) == 12 and all(files == ["raw/tool/sim-smoke/nano17.cal"] for files in ingest.values())


def test_real_session_layouts_read_only_declared_files(tmp_path: Path, smoke_params):
    _require_strace()
    from support.sessions import write_ros
    from support.tool_sim import simulate_public_session
    wd = tmp_path / "project"
    wd.mkdir()
    copy_project(wd, scale="smoke")
    rig, tp = tmp_path / "rig", [str(BIN / "tactilepipe")]
    run(tp + ["tool-simulate", "--scale", "smoke", "--out-dir", str(rig / "tool"), "--trials",
              "paper_knife_p00_normal00"], wd)
    native = wd / "raw/tool/real-native"
    native.mkdir(parents=True)
    shutil.copy(rig / "tool/nano17.cal", native / "nano17.cal")
    shutil.copytree(rig / "tool/paper_knife_p00_normal00", native / "t1")
    public = simulate_public_session(wd / "raw/tool/real-public", smoke_params, n_trials=1)
    (wd / "raw/tool/real-ros").mkdir()
    write_ros(wd / "raw/tool/real-ros/t0.bag", "ros1")
    run(tp + ["drift-simulate", "--scale", "smoke", "--out-dir", str(wd / "raw/drift/real-drift")], wd)
    (wd / "raw/drift/real-drift/notes.txt").write_text("room at 22 C\n")   # provenance.json hashes it too
    config = ["--config", 'tool_sessions=["real-native", "real-public", "real-ros"]', "drift_session=real-drift"]
    targets = [f"{SMOKE}/tool/shards/real-native/t1.parquet", f"{SMOKE}/tool/shards/real-public/data_normal-{public[0]}.parquet",
               f"{SMOKE}/tool/shards/real-ros/t0.parquet", f"{SMOKE}/drift/metrics/loaded.json"]
    audit = audited_snakemake(wd, *targets, *config)             # --config takes every word after it
    jobs = declared_jobs(wd, [*SNAKEMAKE, *config])
    reads = audit.reads()
    ran = {j.rule for j in jobs if j.command in reads}
    assert ran >= {"tool_ingest", "papillarray_ingest", "drift_report"}, ran
    read_files = set().union(*reads.values())
    assert {"raw/tool/real-native/nano17.cal", "raw/tool/real-native/t1/meta.json", "raw/tool/real-public/trials.csv",
            "raw/tool/real-ros/t0.meta.json", "raw/drift/real-drift/session.json",
            "raw/drift/real-drift/notes.txt"} <= read_files
    assert undeclared(reads, [j for j in jobs if j.command in reads]) == {}
    assert undeclared_code(audit.imported(), [j for j in jobs if j.command in reads]) == {}
    assert json.loads((results(wd) / "drift/metrics/loaded.json").read_text())["drift_30min_n"] is not None
