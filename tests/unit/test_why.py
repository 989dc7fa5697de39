"""`tactilepipe why`'s reading of Snakemake's dry runs and logs (pipeline/why.py); through the real
CLI on a smoke build: tests/integration/test_workflow.py."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.pipeline.why import explain, parse_jobs

DRY_RUN = """results/smoke/params/volume-baseline.json: parameters changed: baseline.mu_min 0.1 -> 0.12
Building DAG of jobs...
Job stats:
job                count
---------------  -------
volume_baseline        1
volume_report          1
total                  2

localrule volume_baseline:
    input: results/smoke/volume/dataset.parquet, /tmp/tactilepipe-dry-run-x/changed-params/volume-baseline.json, src/tactilepipe/volume/baseline.py
    output: results/smoke/volume/baseline/mu.json, results/smoke/volume/baseline/folds.csv
    log: results/smoke/logs/volume/volume_baseline.log
    jobid: 3
    reason: Updated input files: /tmp/tactilepipe-dry-run-x/changed-params/volume-baseline.json, src/tactilepipe/volume/baseline.py
    resources: tmpdir=/tmp
localrule volume_report:
    input: results/smoke/volume/baseline/mu.json
    output: results/smoke/volume/metrics.json, results/smoke/volume/scores.json
    jobid: 1
    reason: Input files updated by another job: results/smoke/volume/baseline/mu.json, a, b, c, d
    resources: tmpdir=/tmp
Job stats:
This was a dry-run (flag -n). The order of jobs does not reflect the order of execution.
"""

LOG = """[Sun Nov 29 11:30:24 2026]
localrule volume_report:
    input: results/smoke/volume/baseline/mu.json
    output: results/smoke/volume/metrics.json, results/smoke/volume/scores.json
    jobid: 1
    reason: Missing output files: results/smoke/volume/metrics.json
    wildcards: scene=volume
Shell command: python -m tactilepipe volume-report
[Sun Nov 29 11:32:11 2026]
Finished jobid: 1 (Rule: volume_report)
"""


def test_the_jobs_of_a_dry_run_are_read_with_their_outputs_and_reasons():
    jobs = parse_jobs(DRY_RUN)
    assert [j.rule for j in jobs] == ["volume_baseline", "volume_report"]
    assert jobs[1].output == ["results/smoke/volume/metrics.json", "results/smoke/volume/scores.json"]
    assert jobs[0].reason.startswith("Updated input files:")


def test_a_planned_job_names_the_edited_module_and_the_parameter_key_that_moved():
    said = explain("results/smoke/volume/metrics.json", DRY_RUN, [])
    lines = said.splitlines()
    assert lines[0] == "results/smoke/volume/metrics.json: 2 job(s) would run"
    assert lines[1] == ("  volume_baseline x1: Updated input files: params/volume-baseline.json, "
                        "src/tactilepipe/volume/baseline.py; parameters changed (volume-baseline: baseline.mu_min 0.1 -> 0.12)")
    assert lines[2].endswith("results/smoke/volume/baseline/mu.json, a, b and 2 more")


def test_an_up_to_date_output_is_explained_from_the_newest_log_that_made_it(tmp_path: Path):
    old, new = tmp_path / "2026-11-28.snakemake.log", tmp_path / "2026-11-29.snakemake.log"
    old.write_text(LOG.replace("11:30:24", "09:00:00").replace("Missing output files", "Params have changed"))
    new.write_text(LOG)
    said = explain("results/smoke/volume/metrics.json", "Nothing to be done.", [new, old])
    assert said == ("results/smoke/volume/metrics.json: up to date; last made Sun Nov 29 11:30:24 2026 by rule "
                    "volume_report (scene=volume) (log 2026-11-29.snakemake.log), because: Missing output files: "
                    "results/smoke/volume/metrics.json")
    assert "no Snakemake log here made it" in explain("results/smoke/drift/metrics.json", "Nothing to be done.", [new])
