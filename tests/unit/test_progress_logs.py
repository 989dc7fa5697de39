"""Feedback on long work whatever the terminal: a training run writes one line per epoch, a
stage's parallel jobs a count line when stderr is a log file, and the dry run's estimate takes wall
times from the last build's runtime.json. (Under real Snakemake: tests/integration/test_workflow.py
test_long_jobs_log_their_progress_under_snakemake.)"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from tactilepipe.cli.common import run_parallel
from tactilepipe.pipeline.estimate import estimate_report

from support.tool_data import make_dataset, make_split_dict, quick_cfg


def test_training_writes_one_line_per_epoch_even_without_its_progress_bar(tmp_path, capfd):
    from tactilepipe.tool.data.loader import ToolFrames
    from tactilepipe.tool.model.train import train
    data = ToolFrames(make_dataset(tmp_path / "data", per_trial=6), "normal")
    cfg = quick_cfg(max_epochs=3, max_train_batches_per_epoch=2, bn_recalibration_batches=0)
    train(data, make_split_dict(data), cfg, tmp_path / "run", progress=False)    # what --quiet asks for
    err = capfd.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("epoch ")]
    assert [line.split(":")[0] for line in lines] == ["epoch 1/3", "epoch 2/3", "epoch 3/3"], err
    elapsed = []
    for line in lines:
        m = re.fullmatch(r"epoch \d/3: train loss [\d.]+, val loss [\d.]+, val MAE [\d.]+ N, [\d.]+ s "
                         r"\(elapsed ([\d.]+) s\)", line)
        assert m, line
        elapsed.append(float(m.group(1)))
    assert elapsed == sorted(elapsed) and elapsed[-1] > 0
    assert "\r" not in err                                  # no progress bar in a log file


def _nothing(_):
    pass


def test_parallel_jobs_write_counts_when_stderr_is_a_file(capfd):
    run_parallel([(_nothing, k) for k in range(25)], 1, "simulate volume")
    lines = capfd.readouterr().err.splitlines()
    counts = [re.fullmatch(r"simulate volume: (\d+)/25 done \([\d.]+ s\)", line).group(1) for line in lines]
    assert counts == ["2", "4", "6", "8", "10", "12", "14", "16", "18", "20", "22", "24", "25"]


@pytest.fixture
def last_build(tmp_path, smoke_params) -> Path:
    """A project whose last smoke build left run times: two tool runs, two volume methods."""
    for scene, times in (("tool_normal", {"full": {"train_s": 90.0, "latency_ms": 2.0},
                                          "no_ref": {"train_s": 30.0, "latency_ms": 1.0}}),
                         ("volume", {"fz": {"fit_s": 6.0, "predict_us_per_sample": 0.1},
                                     "baseline": {"fit_s": 1.5, "predict_us_per_sample": 0.1}})):
        folder = tmp_path / "results" / smoke_params["build"] / scene
        folder.mkdir(parents=True)
        (folder / "runtime.json").write_text(json.dumps(times))
    return tmp_path


JOBS = [("tool_train", {"scene": "tool_normal", "run": run}, {"runtime": 60}, 2) for run in ("full", "no_ref", "single")] + \
    [("volume_train", {"modality": "fz"}, {"runtime": 30}, 1), ("volume_baseline", {}, {"runtime": 30}, 1),
     ("tool_ingest", {"session": "sim-smoke", "trial": "t0"}, {"runtime": 10}, 1)]


def measured_rows(text: str) -> dict[str, list[str]]:
    part = text.split("Measured wall time", 1)[1]
    return {line.split()[0]: line.split() for line in part.splitlines()[2:] if line.split()}


def test_the_estimate_takes_wall_time_from_the_last_builds_runtime_json(last_build, smoke_params):
    text = estimate_report(smoke_params, JOBS, root=last_build)
    rows = measured_rows(text)
    # tool_train: 3 jobs, 2 with a record: 90 s + 30 s = 2.0 min, 1.0 min per run
    assert rows["tool_train"][1:] == ["3", "2", "2.0", "min", "1.0", "min"], text
    # the volume jobs: fit_s per fold x 2 folds at the smoke scale: 12 s, 3 s
    assert rows["volume_train"][1:4] == ["1", "1", "0.2"] and rows["volume_baseline"][1:4] == ["1", "1", "0.1"]
    assert "tool_ingest" not in rows                    # no run time is recorded for ingest
    assert rows["total"][1:5] == ["5", "4", "2.2", "min"] and "1 without a record" in text


def test_without_a_last_build_the_estimate_says_so(tmp_path, smoke_params):
    text = estimate_report(smoke_params, JOBS, root=tmp_path)
    assert "no run times of a last build (results/smoke/<scene>/runtime.json)" in text


def test_an_unreadable_runtime_json_is_left_out_not_fatal(last_build, smoke_params):
    (last_build / "results/smoke/volume/runtime.json").write_text("{not json")
    rows = measured_rows(estimate_report(smoke_params, JOBS, root=last_build))
    assert rows["volume_train"][1:3] == ["1", "0"] and rows["tool_train"][2] == "2"
