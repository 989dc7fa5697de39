"""Scale-out: per-rule resources, the paper-scale dry run with its compute estimate,
device selection and mixed precision, and the smoke scale through a real single-node SLURM
cluster (`slurm` marker: needs root; installs slurm-wlm and munge with apt when missing). That test
runs only with TACTILEPIPE_SLURM_TEST=1: `.ci/run` sets it for `make test`, where the run through
the cluster is compared with the session's shared smoke build; `make test-slurm` runs it alone."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

from tactilepipe.core.config import load_params
from tactilepipe.core.errors import TactilepipeError
from tactilepipe.core.parameters.resources import RuleResources
from tactilepipe.pipeline.estimate import estimate_report
from tactilepipe.tool.estimate import forward_flops, planned_pairs, training_flops
from tactilepipe.pipeline.stage_rules import stage_rules

from support.project import BIN, REPO, SMOKE, copy_project, results, run

CLUSTER = REPO / ".ci" / "slurm-cluster"


# ----------------------------------------------------------------------------- declared resources

def rule_blocks() -> dict[str, str]:
    blocks = {}
    for smk in sorted((REPO / "workflow/rules").glob("*.smk")):
        for block in re.split(r"(?m)^(?=rule )", smk.read_text())[1:]:
            blocks[re.match(r"rule (\w+):", block).group(1)] = block
    return blocks


def test_every_rule_that_runs_something_declares_its_resources():
    blocks = rule_blocks()
    runs = {name for name, b in blocks.items() if re.search(r"(?m)^    (shell|run|script):", b)}
    assert runs >= {"tool_train", "tool_simulate", "volume_train", "papillarray_ingest"}
    for name in runs:
        assert f'**rule_resources("{name}")' in blocks[name], name
    # the rules generated from the stages' declarations ask for theirs by the same name: an entry
    # of their own where they have one, else resources.default (a new stage needs none)
    assert "**rule_resources(_stage.name)" in (REPO / "workflow/rules/stages.smk").read_text()
    declared = {r.name for r in stage_rules()}
    # params.yaml names every hand-written rule, and no rule that does not exist (the schema
    # refuses a misspelt one)
    assert runs <= set(RuleResources.model_fields) <= runs | declared
    assert set(load_params(REPO / "params.yaml")["resources"]["rules"]) == set(RuleResources.model_fields)


@pytest.mark.parametrize("scale, gpu", [("smoke", 0), ("default", 0), ("paper", 1)])
def test_the_network_asks_for_a_gpu_only_at_the_paper_scale(scale, gpu):
    p = load_params(REPO / "params.yaml", {"scale": scale})
    res = {**p["resources"]["default"], **p["resources"]["rules"]["tool_train"]}
    assert res["gpu"] == gpu
    # the other rule that runs the network at the paper's size: the published weights over every frame
    assert {**p["resources"]["default"], **p["resources"]["rules"]["study000_evaluate_published"]}["gpu"] == gpu
    others = [r for r in p["resources"]["rules"] if r not in ("tool_train", "study000_evaluate_published")]
    assert all({**p["resources"]["default"], **p["resources"]["rules"][r]}["gpu"] == 0 for r in others)
    if scale == "paper":
        assert res["runtime"] >= 24 * 60 and res["mem_mb"] >= 16000


def test_a_wrong_resource_key_stops_with_its_name(tmp_path):
    from tactilepipe.core.errors import ConfigError
    with pytest.raises(ConfigError, match=r"resources.rules.*tool_trian"):
        load_params(REPO / "params.yaml", {"resources": {"rules": {"tool_trian": {"gpu": 1}}}})
    with pytest.raises(ConfigError, match=r"resources.rules.tool_train.gpu"):
        load_params(REPO / "params.yaml", {"resources": {"rules": {"tool_train": {"gpu": -1}}}})


# ----------------------------------------------------------------------------- compute estimate

def test_forward_flops_follow_the_image_area():
    f112, f224 = forward_flops("full", 101, 112, "sigmoid", 64), forward_flops("full", 101, 224, "sigmoid", 64)
    assert 3.6 < f224 / f112 < 4.4                 # convolutions: cost grows with the image area
    assert forward_flops("single", 101, 224, "sigmoid", 64) < f224  # one finger's encoder and GAM less


def test_estimate_report_counts_jobs_and_models_training():
    p = load_params(REPO / "params.yaml", {"scale": "paper"})
    spec = {"full": ("full", "trial", 101, 224), "full_d101_s112": ("full", "trial", 101, 112)}
    gpu = {"mem_mb": 32000, "runtime": 2880, "gpu": 1}
    jobs = [("tool_train", {"scene": "tool_normal", "run": r}, gpu, 2) for r in spec] + \
           [("tool_ingest", {"session": "sim-paper", "trial": f"t{i}"}, {"mem_mb": 4000, "runtime": 60}, 1)
            for i in range(3)]
    text = estimate_report(p, jobs, run_spec=spec.__getitem__, root=Path("/nonexistent"))
    print("\n" + text)
    row = {line.split()[0]: line.split() for line in text.splitlines() if line.split()}
    assert row["tool_ingest"][1] == "3" and row["tool_ingest"][-2] == "3.0"     # 3 jobs x 1 core x 1 h
    assert row["tool_train"][1] == "2" and row["tool_train"][-1] == "96.0"       # 2 x 1 GPU x 48 h booked
    pairs = planned_pairs(p, "tool_normal", Path("/nonexistent"))
    assert pairs == 4 * 3 * 3 * 1100                         # tools x poses x normal trials x frames
    assert planned_pairs(p, "tool_shear", Path("/nonexistent")) == 4 * 3 * 2 * 1100   # sliding trials
    at15 = {**p, "tool_sync": {**p["tool_sync"], "pair_rate_hz": 15}}      # 30-FPS frames paired at 15 FPS
    assert planned_pairs(at15, "tool_normal", Path("/nonexistent")) == 4 * 3 * 3 * 550
    t = training_flops(p, pairs, "full", 101, 224)
    expected_h = t["flop"] / (p["resources"]["cost_model"]["gpu_tflops"] * 1e12) / 3600
    assert t["epochs"] == 300 and t["train_pairs"] == int(pairs * 0.7)
    assert f"{expected_h:,.1f} h" in text
    assert "warning" not in text


def test_estimate_warns_when_the_time_limit_is_too_short():
    p = load_params(REPO / "params.yaml", {"scale": "paper"})
    jobs = [("tool_train", {"scene": "tool_normal", "run": "full"}, {"mem_mb": 1, "runtime": 10, "gpu": 1}, 2)]
    text = estimate_report(p, jobs, run_spec=lambda run: ("full", "trial", 101, 224), root=Path("/nonexistent"))
    assert "warning: modelled time above the job's time limit" in text and "tool_normal/full" in text


@pytest.mark.integration
def test_paper_dry_run_prints_the_estimate_and_builds_nothing(tmp_path):
    wd = copy_project(tmp_path)
    proc = run([str(BIN / "snakemake"), "-n", "--cores", "2", "--config", "scale=paper"], wd)
    out = proc.stdout
    assert "Compute estimate" in out and "Modelled training" in out
    # all variants of both targets on each of the paper scale's 5 repeated splits, leave-one-tool-out
    # of each of the 4 tools, and the backbone/size sweep
    train_rows = [l for l in out.splitlines() if re.match(r"tool_(normal|shear)\s+\w+\s+\w+\s+\d+\s+\d+\s+[\d,]+", l)]
    assert len(train_rows) == 2 * (4 * 5 + 4 + 3)
    assert all(" GPU" in l for l in train_rows)
    assert re.search(r"(?m)^tool_train\s+54\s+\d+\s+1\s+32\.0GB\s+48\.0 h", out)
    # every training job asks for a GPU; the 224-px data is planned, never written
    assert re.search(r"rule tool_train:(?:\n    .*)*\n    resources: .*gpu=1", out)
    # a dry run writes nothing: no recordings, no results, not even the rules' parameter stamps
    assert not (wd / "raw").exists() and not (wd / "results").exists()
    # a smoke-scale dry run books no GPU
    smoke = run([str(BIN / "snakemake"), "-n", "--cores", "2", "--config", "scale=smoke"], wd).stdout
    assert re.search(r"(?m)^tool_train\s+24\s+\d+\s+0\s", smoke) and "gpu=1" not in smoke   # 2 x (4 x 2 + 3 + 1)


# ----------------------------------------------------------------------------- device and precision

@pytest.fixture
def tiny_data(tmp_path):
    from support.tool_data import make_dataset, make_split_dict
    from tactilepipe.tool.data.loader import ToolFrames
    root = make_dataset(tmp_path / "data", n_trials=8, per_trial=6)
    split = make_split_dict(ToolFrames(root, "normal"))
    (tmp_path / "split.json").write_text(json.dumps(split))
    return root, tmp_path / "split.json", split


@pytest.mark.skipif(torch.cuda.is_available(), reason="checks the error when CUDA is missing")
def test_device_cuda_without_cuda_is_one_clear_error(tiny_data, tmp_path):
    from tactilepipe.tool.model.train import resolve_device
    assert resolve_device("auto").type == "cpu"
    with pytest.raises(TactilepipeError, match="device 'cuda' requested but CUDA is not available"):
        resolve_device("cuda")
    # through the CLI: params.yaml's tool_train.device reaches the trainer (with native kernels, as a
    # GPU run must set; portable kernels on cuda are refused earlier, by the params check)
    root, split, _ = tiny_data
    proc = run([str(BIN / "tactilepipe"), "tool-train", "--params", str(REPO / "params.yaml"), "--scale", "smoke",
                "--override", json.dumps({"tool_train": {"device": "cuda", "kernels": "native"}}), "--scene", "tool_normal",
                "--run", "full", "--data-dir", str(root), "--split", str(split),
                "--out-dir", str(tmp_path / "out"), "--quiet"], tmp_path, check=False)
    assert proc.returncode == 2
    assert proc.stderr.strip() == "tactilepipe tool-train: error: device 'cuda' requested but CUDA is not available"
    assert not (tmp_path / "out" / "best.pt").exists()


def test_mixed_precision_only_on_cuda(tiny_data, tmp_path, monkeypatch):
    from tactilepipe.tool.model import train as train_mod
    from tactilepipe.tool.data.loader import ToolFrames
    root, _, split = tiny_data
    calls = []
    real = torch.autocast

    def spy(device_type, *args, **kwargs):
        calls.append((device_type, kwargs.get("enabled")))
        return real(device_type, *args, **kwargs)

    monkeypatch.setattr(train_mod.torch, "autocast", spy)
    from support.tool_data import quick_cfg
    cfg = quick_cfg(image_size=32, batch_size=8, max_epochs=1, seed=1, device="cpu", amp=True,
                    max_train_batches_per_epoch=1)
    summary = train_mod.train(ToolFrames(root, "normal"), split, cfg, tmp_path / "cpu", progress=False)
    assert summary["device"] == "cpu"
    assert calls and all(c == ("cpu", False) for c in calls)       # amp=True is ignored on CPU


def test_the_cli_hands_device_and_amp_to_the_trainer(tiny_data, tmp_path, monkeypatch):
    from tactilepipe.cli import main as cli
    from tactilepipe.tool.model import train as train_mod
    root, split, _ = tiny_data
    seen = {}

    def fake_train(data, split, cfg, out_dir, progress=True):
        seen["cfg"] = cfg
        raise TactilepipeError("stop here")

    monkeypatch.setattr(train_mod, "train", fake_train)
    code = cli.main(["tool-train", "--params", str(REPO / "params.yaml"), "--scale", "smoke", "--override",
                     json.dumps({"tool_train": {"device": "cuda", "amp": False, "kernels": "native"}}),
                     "--scene", "tool_normal",
                     "--run", "full", "--data-dir", str(root), "--split", str(split),
                     "--out-dir", str(tmp_path / "out"), "--quiet"])
    assert code == 2
    assert seen["cfg"].device == "cuda" and seen["cfg"].amp is False and seen["cfg"].kernels == "native"


# ----------------------------------------------------------------------------- a real SLURM cluster

SLURM_FLAGS = [
    "--slurm-no-account",                         # a test cluster has no accounts
    "--slurm-status-command", "squeue",           # no slurmdbd: sacct answers nothing; MinJobAge keeps jobs in squeue
    "--slurm-init-seconds-before-status-checks", "1",
    "--seconds-between-status-checks", "2",
    "--latency-wait", "5",
]


# what the cluster builds: every rule of the volume and drift scenes, and of the tool scenes'
# data stages with one training run (the smoke build trains 24 more the same way)
CLUSTER_TARGETS = ["volume/metrics/fy_fz.json", "drift/metrics/loaded.json", "tool_normal/models/full/eval.json"]
CLUSTER_RUNS = ["tool_normal/models/full"]


def comparable(wd: Path) -> dict:
    """The results that must not depend on where a job ran (no run times)."""
    out = {}
    vm = json.loads((results(wd) / "volume/scores.json").read_text())
    out["volume"] = {k: vm[k] for k in ("r2", "mu_star", "unseen_ml")}
    dm = json.loads((results(wd) / "drift/scores.json").read_text())
    out["drift"] = dm["drift_30min_n"]
    for run in CLUSTER_RUNS:
        e = json.loads((results(wd) / run / "eval.json").read_text())
        out[run] = {k: e[k] for k in ("mae", "rmse", "r2", "n", "epochs", "best_epoch")}
        pred = pd.read_parquet(results(wd) / run / "predictions.parquet")
        out[f"{run}/pred"] = np.round(pred["pred"].to_numpy(), 10).tolist()
    return out


@pytest.fixture(scope="module")
def slurm_cluster():
    if os.geteuid() != 0:
        pytest.skip("a SLURM test cluster needs root (apt-get install, slurmd)")
    if shutil.which("slurmctld") is None and shutil.which("apt-get") is None:
        pytest.skip("SLURM is not installed and there is no apt-get to install it")
    run(["bash", str(CLUSTER), "install"], REPO)
    already = subprocess.run(["bash", str(CLUSTER), "start"], capture_output=True, text=True)
    if already.returncode != 0:
        raise AssertionError(f"could not start the test cluster:\n{already.stdout}\n{already.stderr}")
    started_here = "cluster already running" not in already.stderr     # else another run's: leave it up
    yield Path(os.environ.get("SLURM_TEST_DIR", "/tmp/tactilepipe-slurm"))
    if started_here:
        subprocess.run(["bash", str(CLUSTER), "stop"], capture_output=True, text=True)


@pytest.mark.slurm
@pytest.mark.skipif(os.environ.get("TACTILEPIPE_SLURM_TEST") != "1",      # before any fixture: no smoke build
                    reason="installs and starts SLURM, then ~80 jobs through it: run with `make test-slurm` "
                           "(sets TACTILEPIPE_SLURM_TEST=1)")
def test_smoke_scale_through_slurm_equals_the_local_run(slurm_cluster, smoke_build, tmp_path):
    """The local run is the test session's shared smoke build (tests/integration/conftest.py): the
    cluster runs a copy of the same project, with the same parameter file, through the scheduler."""
    jobcomp = slurm_cluster / "jobcomp.log"
    before = jobcomp.read_text().count("\n") if jobcomp.exists() else 0

    (tmp_path / "cluster").mkdir()
    # the copy runs its own copy of the package (support.project.run sets PYTHONPATH; sbatch
    # --export=ALL passes it on), so it runs the code the smoke build ran even while the working
    # tree is edited
    cluster = copy_project(tmp_path / "cluster", scale="smoke")
    proc = run([str(BIN / "snakemake"), "--workflow-profile", "workflow/profiles/slurm", *SLURM_FLAGS,
                *(f"{SMOKE}/{t}" for t in CLUSTER_TARGETS)], cluster)
    log = proc.stdout + proc.stderr

    # every job but the local rules' went through the scheduler: an sbatch job id each, a SLURM
    # log each, and the scheduler's own completion record for each of those ids
    submitted = dict(re.findall(r"Job (\d+) has been submitted with SLURM jobid (\d+)", log))
    stats = log[log.index("Job stats:"):]
    planned = {rule: int(n) for rule, n in re.findall(r"(?m)^(\w+)\s+(\d+)$", stats[:stats.index("total")])}
    local = set(re.findall(r"(?m)^localrule (\w+):$", log))
    assert local == {"papillarray_ingest", "tool_split", "volume_split"}, local    # the localrules
    assert {"tool_simulate", "tool_ingest", "tool_dataset", "tool_train", "volume_train", "drift_report"} <= set(planned)
    assert len(submitted) == sum(n for rule, n in planned.items() if rule not in local) >= 20
    slurm_logs = list((cluster / ".snakemake/slurm_logs").rglob("*.log"))
    assert {p.stem for p in slurm_logs} == set(submitted.values())
    records = jobcomp.read_text().splitlines()[before:]
    completed = {m.group(1) for r in records if (m := re.search(r"JobId=(\d+) .*JobState=COMPLETED", r))}
    assert set(submitted.values()) <= completed
    # training ran under SLURM with the rule's threads as CPUs, and wrote the same numbers
    train_log = next((cluster / ".snakemake/slurm_logs/rule_tool_train").rglob("*.log")).read_text()
    threads = load_params(REPO / "params.yaml", {"scale": "smoke"})["tool_train"]["num_threads"]
    header = train_log[train_log.index("rule tool_train:"):].split("Shell command:")[0]
    # Snakemake names the threads in a job's header only when they are more than one
    assert (f"threads: {threads}" in header) if threads > 1 else ("threads:" not in header)
    assert comparable(cluster) == comparable(smoke_build)
