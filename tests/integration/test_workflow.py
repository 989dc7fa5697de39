"""End to end through the real Snakemake and DVC command lines, at the smoke scale. The tests
that read a whole build share one (`smoke_build`, tests/integration/conftest.py)."""

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
import yaml

from tactilepipe.core.config import load_params
from tactilepipe.tool.model.network import PAPER_WIDTH, build_model, count_parameters
from tactilepipe.tool.model.checkpoint import load_checkpoint
from tactilepipe.tool.report.portability import run_digests
from tactilepipe.tool.runs import sweep_run_name, tool_runs

from support.hostile import billion_laughs
from support.project import BIN, ENV, REPO, SMOKE, copy_project, results, run, snakemake

pytestmark = pytest.mark.integration


def linked_copy(src: Path, dest: Path) -> Path:
    """A copy of a built project in which every file is a hard link (same bytes and file times, no
    data copied). For dry runs only: what they write (Snakemake's records) is
    written to a temporary and renamed, which replaces the link, but a job writing in place would
    change both copies."""
    shutil.copytree(src, dest, symlinks=True, copy_function=os.link)
    return dest


def test_smoke_builds_every_target_of_both_scenes(smoke_build: Path):
    wd = smoke_build
    m = json.loads((results(wd) / "volume/scores.json").read_text())
    assert set(m["r2"]) == {"fx_fy_fz", "fy_fz", "fy", "fz", "baseline"}
    # DVC's metrics are the headline alone, a row per input: its mean R²; the best one's gain, the baseline's μ*
    for k, v in m["r2"].items():
        extra = {"r2_gain": m["best_minus_baseline"]["mean"]} if k == m["best_modality"] else \
            {"mu_star": m["mu_star"]} if k == "baseline" else {}
        assert json.loads((results(wd) / f"volume/metrics/{k}.json").read_text()) == {"r2": v["mean"], **extra}, k
    for method, r2 in m["r2"].items():
        assert set(r2) >= {"mean", "std"} and all(isinstance(v, float) for v in r2.values()), method
    assert 0.1 <= m["mu_star"] <= 0.4
    assert set(m["unseen_ml"]) == {"75", "125"}
    # even the smoke scale separates the methods: the MLP with Fy beats the algebraic baseline
    assert m["r2"]["fy_fz"]["mean"] > m["r2"]["baseline"]["mean"] + 0.1
    # Table 1's intervals: around each mean, and the paired best-MLP-minus-baseline difference
    for method, (low, high) in m["r2_ci95"].items():
        assert low < m["r2"][method]["mean"] < high, method
    diff = m["best_minus_baseline"]
    assert diff["modality"] == m["best_modality"] and len(diff["per_fold"]) == len(m["r2_folds"]["baseline"])
    assert diff["ci95"][0] < diff["mean"] < diff["ci95"][1]
    assert diff["beats_baseline"] == (diff["ci95"][0] > 0)
    assert "paired difference" in (results(wd) / "volume/tables/table1_r2.md").read_text()
    assert m["modality_ranking"].split()[::2] == m["modality_order"]
    for table in ("table1_r2", "table2_volumes", "unseen_volumes", "runtime", "grid_search"):
        assert (results(wd) / f"volume/tables/{table}.csv").stat().st_size > 0
        assert (results(wd) / f"volume/tables/{table}.md").read_text().count("|") > 10
    for fig in ("r2_by_modality", "mu_r2_curve", "true_vs_estimated", "error_vs_runtime", "pillar_map"):
        assert (results(wd) / f"volume/figures/{fig}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    d = {run: json.loads((results(wd) / f"drift/metrics/{run}.json").read_text()) for run in ("loaded", "unloaded")}
    assert d["loaded"]["drift_30min_n"] > d["unloaded"]["drift_30min_n"] > 0
    assert (results(wd) / "drift/figures/drift_curves.png").exists()
    for scene in ("tool_normal", "tool_shear"):
        for split in ("frame", "trial", "trial_r1", "loto_spatula", "loto_paper_knife", "lopo"):
            split_json = json.loads((results(wd) / f"{scene}/splits/{split}.json").read_text())
            assert split_json["train"] and split_json["test"]
        for fig in ("pressing_strip", "rmse_vs_force", "force_profiles", "force_histogram"):
            assert (results(wd) / f"{scene}/figures/{fig}.png").read_bytes()[:4] == b"\x89PNG"
        assert "| trial |" in (results(wd) / f"{scene}/qc.md").read_text()
        # every simulated trial of the scene's kind is kept: none left out by a witness or the clock
        qc = json.loads((results(wd) / f"{scene}/data/qc.json").read_text())
        kind = scene.removeprefix("tool_")
        simulated = sorted(p.name for p in (wd / "raw/tool/sim-smoke").iterdir() if f"_{kind}" in p.name)
        assert qc["dropped_trials"] == [] and simulated, (scene, qc["dropped_trials"])
        assert sorted(t["trial"].split("/")[-1] for t in qc["trials"]) == simulated, scene
        # every model variant trained and evaluated, with the report's tables and figures
        tm = json.loads((results(wd) / f"{scene}/scores.json").read_text())
        assert tm["repeats"] == 2 and tm["splits"] == ["trial", "trial_r1"]
        assert tm["first_split"]["split"] == "trial" and "split" not in tm and "test_pairs" not in tm
        # DVC's metrics are the headline alone, a row per variant: its mean scores (the top-level keys)
        for v in ("full", "no_ref", "single", "no_gam"):
            assert json.loads((results(wd) / f"{scene}/metrics/{v}.json").read_text()) == \
                {m: tm[v][m] for m in ("mae", "rmse", "r2")}, (scene, v)
        for name, t in [(v, tm[v]) for v in ("full", "no_ref", "single", "no_gam")] + list(tm["baselines"].items()):
            assert not {"train_s", "latency_ms"} & set(t), "run times belong in runtime.json"
            # a model's scores are its means over the splits, the interval beside them; the first
            # split's values (the figures' and the variants table's) under a name that says so
            for m in ("mae", "rmse", "r2"):
                assert len(t["per_split"][m]) == 2 and t[m] == t["over_splits"][m]["mean"], (scene, name, m)
                assert t["first_split"][m] == t["per_split"][m][0] != t[m], (scene, name, m)
            assert t["first_split"]["split"] == "trial" and {"slope", "intercept"} <= set(t["first_split"]), name
            assert not {"slope", "intercept"} & set(t), name
            o = t["over_splits"]["mae"]
            assert o["n"] == 2 and o["low"] <= o["mean"] <= o["high"] and o["mean"] == pytest.approx(np.mean(t["per_split"]["mae"]))
            if name in tm["baselines"]:
                continue
            variant = name
            # like-for-like verdicts, and the paired difference to the full model for each ablation
            assert t["like_for_like_baseline"] == {"full": "tactile_rmse_linear", "no_gam": "tactile_rmse_linear",
                                                   "no_ref": "rest_frame_rmse_linear",
                                                   "single": "one_finger_rmse_linear"}[variant]
            assert set(t["versus_baselines"]) == {t["like_for_like_baseline"], "mean_predictor"}
            assert t["beats_baselines"] == all(a["beats"] for a in t["versus_baselines"].values())
            if variant != "full":
                d = t["minus_full"]["mae"]
                assert d["per_draw"] == pytest.approx(np.subtract(t["per_split"]["mae"], tm["full"]["per_split"]["mae"]))
        assert set(tm["baselines"]) == {"mean_predictor", "tactile_rmse_linear", "rest_frame_rmse_linear",
                                        "one_finger_rmse_linear"}
        assert sorted(tm["ablation_ranking_by_mae"].split()[::2]) == sorted(tm["ablation_order_by_mae"])
        # leave-one-tool-out: every tool of the smoke session held out in turn, with the mean over tools
        assert set(tm["loto"]["per_tool"]) == {"screwdriver_1", "paper_knife", "spatula"}
        assert tm["loto"]["over_tools"]["mae"]["n"] == 3
        assert tm["paper_orderings"] and {o["verdict"] for o in tm["paper_orderings"]} <= {"holds", "reversed",
                                                                                           "equivalent", "undecided"}
        runtime = json.loads((results(wd) / f"{scene}/runtime.json").read_text())
        assert all(r["train_s"] > 0 and r["latency_ms"] > 0 for r in runtime.values()) and "full" in runtime
        prov = json.loads((results(wd) / f"{scene}/provenance.json").read_text())
        assert prov["sessions"] == {"raw/tool/sim-smoke": prov["sessions"]["raw/tool/sim-smoke"]}
        # DVC's hash of the session folder (tests/unit/test_provenance_hash.py: the one `dvc add` records)
        assert re.fullmatch(r"[0-9a-f]{32}\.dir", prov["sessions"]["raw/tool/sim-smoke"])
        assert prov["stages"]["tool-train"]["params"]["tool_train"]["lr"] > 0
        assert set(prov["environment"]["packages"]) == {"torch", "numpy", "scikit-learn", "pandas", "snakemake", "dvc",
                                                        "dvc-data"}
        for table in ("variants", "intervals", "differences", "paper_orderings", "per_tool", "per_window", "runtime",
                      "loto"):
            assert (results(wd) / f"{scene}/tables/{table}.md").read_text().count("|") > 10
        assert len(runtime) == 4 * 2 + 3 + 1           # variants x repeats, one per held-out tool, the sweep
        for fig in ("sorted_predictions", "over_time", "per_tool", "window_heatmap", "regression",
                    "error_vs_runtime", "intervals", "loto"):
            assert (results(wd) / f"{scene}/figures/{fig}.png").read_bytes()[:4] == b"\x89PNG"
    # every rule logs; raw recordings are bags, shards are Parquet
    assert len(list((results(wd) / "logs").rglob("*.log"))) > 10
    assert list((wd / "raw/volume/sim-smoke").glob("*.bag")) and (wd / "raw/volume/sim-smoke/lifts.csv").exists()


def test_every_ordering_verdict_follows_its_stored_interval_and_margin(smoke_build: Path):
    """Each judged ordering of the smoke build (and the full model against its like-for-like
    baseline) carries the verdict its interval and margin give, in scores.json and in the table."""
    from tactilepipe.core.intervals import half_width
    for scene in ("tool_normal", "tool_shear"):
        tm = json.loads((results(smoke_build) / f"{scene}/scores.json").read_text())
        margin = tm["equivalence_margin"]["n"]
        assert tm["equivalence_margin"]["fraction_of_full_mae"] == 0.1
        assert margin == pytest.approx(0.1 * tm["full"]["over_splits"]["mae"]["mean"])
        rows = tm["paper_orderings"] + [tm["full_versus_baseline"]]
        assert tm["full_versus_baseline"]["claim"] == "full < tactile_rmse_linear (MAE)"
        for r in rows:
            low, high = r["low"], r["high"]
            expected = "equivalent" if -margin < low and high < margin else \
                "holds" if low > 0 else "reversed" if high < 0 else "undecided"
            assert r["margin"] == margin and r["verdict"] == expected, (scene, r)
            assert (r["equivalence_p"] < 0.025) == (expected == "equivalent"), (scene, r)
            assert bool(r["power"]) == (expected == "undecided"), (scene, r)
            # any K the power line names narrows the interval enough (the spread read back off it)
            for key, target in (("repeats_to_order", abs(r["mae_difference"])),
                                ("repeats_to_equivalence", margin - abs(r["mae_difference"]))):
                if r[key] is not None:
                    spread = (high - low) / 2 / half_width(1.0, tm["repeats"], test_train_ratio=tm["test_train_ratio"])
                    assert half_width(spread, r[key], test_train_ratio=tm["test_train_ratio"]) < target, (scene, r)
        table = pd.read_csv(results(smoke_build) / f"{scene}/tables/paper_orderings.csv")
        assert list(table["verdict"]) == [r["verdict"] for r in rows]
        assert list(table["claim"]) == [r["claim"] for r in rows]
        assert np.allclose(table["margin"], margin)


def test_second_run_has_nothing_to_do(smoke_build: Path):
    proc = snakemake(smoke_build, "-n", "--config", "scale=smoke")
    assert "Nothing to be done" in proc.stdout + proc.stderr


def test_changing_a_model_parameter_reruns_only_what_depends_on_it(smoke_build: Path, tmp_path: Path):
    wd = linked_copy(smoke_build, tmp_path / "wd")       # params.yaml is edited below
    params = wd / "params.yaml"
    original = params.read_text()
    assert "  mu_min: 0.1\n" in original
    params.unlink()                                      # a file of its own, not the shared link
    params.write_text(original.replace("  mu_min: 0.1\n", "  mu_min: 0.12\n"))
    out = snakemake(wd, "-n", "--config", "scale=smoke").stdout
    planned = set(re.findall(r"^(?:local)?rule (\w+):$", out, flags=re.M)) - {"all"}   # job headers, not file lists
    assert planned == {"volume_baseline", "volume_report"}, planned
    # `tactilepipe why` names the jobs and the key that moved, with no Snakemake output to read
    why = run([str(BIN / "tactilepipe"), "why", f"{SMOKE}/volume/metrics/baseline.json"], wd).stdout
    assert f"{SMOKE}/volume/metrics/baseline.json: 2 job(s) would run" in why, why
    assert "volume_baseline x1:" in why and "parameters changed (volume-baseline: baseline.mu_min 0.1 -> 0.12)" in why, why
    assert "volume_report x1: Input files updated by another job" in why, why


def test_why_says_when_and_why_an_up_to_date_output_was_made(smoke_build: Path):
    why = run([str(BIN / "tactilepipe"), "why", f"{SMOKE}/tool_normal/models/full/eval.json"], smoke_build).stdout
    assert f"{SMOKE}/tool_normal/models/full/eval.json: up to date; last made " in why, why
    assert "by rule tool_train (scene=tool_normal, run=full)" in why and "because: Missing output files" in why, why
    bad = run([str(BIN / "tactilepipe"), "why", "results/nowhere.txt"], smoke_build, check=False)
    assert bad.returncode != 0 and "results/nowhere.txt: Snakemake cannot plan it" in bad.stderr, bad.stderr


def test_a_nested_config_override_is_typed_as_params_yaml_has_it(smoke_build: Path, tmp_path: Path):
    wd = linked_copy(smoke_build, tmp_path / "wd")       # dry runs only: a copy keeps the shared build out of reach
    out = snakemake(wd, "-n", "--config", "scale=smoke", 'folds={"n_folds": 3}')
    planned = set(re.findall(r"^(?:local)?rule (\w+):$", out.stdout, flags=re.M)) - {"all"}
    assert "volume_split" in planned and "papillarray_ingest" not in planned, planned   # n_folds 3, an integer
    bad = snakemake(wd, "-n", "--config", "scale=smoke", 'folds={"n_folds": "three"}', check=False)
    assert bad.returncode != 0 and "'folds.n_folds': 'three' is not of type 'integer'" in bad.stdout + bad.stderr


def test_a_scene_pulls_in_only_its_rules(tmp_path: Path):
    wd = copy_project(tmp_path)
    out = snakemake(wd, "-n", "--config", "scale=smoke", "scenes=[drift]").stdout
    assert "drift_simulate" in out and "drift_report" in out
    for rule in ("volume_simulate", "volume_dataset", "volume_train", "volume_report", "tool_simulate", "tool_ingest"):
        assert rule not in out, rule


def test_plain_snakemake_uses_the_default_profile(tmp_path: Path):
    # Snakemake looks for profiles/default next to the Snakefile or in the working directory, not
    # in workflow/profiles: the top-level `profiles` link is what makes a bare `snakemake --cores 2`
    # record input checksums (max-checksum-file-size) and rerun incomplete jobs as documented
    assert (REPO / "profiles").is_symlink() and (REPO / "profiles").resolve() == (REPO / "workflow/profiles").resolve()
    wd = copy_project(tmp_path)
    proc = snakemake(wd, "-n", "--config", "scale=smoke", "scenes=[drift]")
    assert "Using workflow specific profile" not in proc.stdout + proc.stderr   # no link in the copy yet
    (wd / "profiles").symlink_to("workflow/profiles")
    proc = snakemake(wd, "-n", "--config", "scale=smoke", "scenes=[drift]")
    out = proc.stdout + proc.stderr
    assert "Using workflow specific profile profiles/default" in out


@pytest.mark.slow
def test_a_named_build_of_a_simulated_session_builds_to_the_end(tmp_path: Path):
    """A named build shares its scale's simulated session, and the simulator's stamp with it
    (results/<scale>/params/, decision 0025): its report reads that stamp for provenance.json."""
    wd = copy_project(tmp_path)
    snakemake(wd, "--config", "scale=smoke", "build=alt", "scenes=[drift,volume]")
    assert (results(wd, "alt") / "drift/metrics/loaded.json").is_file()
    volume = json.loads((results(wd, "alt") / "volume/provenance.json").read_text())
    assert "volume-simulate" in volume["stages"] and (results(wd, "alt") / "volume/metrics/baseline.json").is_file()
    prov = json.loads((results(wd, "alt") / "drift/provenance.json").read_text())
    stamp = json.loads((results(wd, "smoke") / "params/drift-simulate.json").read_text())
    assert prov["stages"]["drift-simulate"]["params"]["simulate_drift"] == stamp["values"]["simulate_drift"]
    assert stamp["values"]["simulate_drift"]["rate_hz"] == 100                # the smoke scale's, not the default's
    assert not (results(wd, "alt") / "params/drift-simulate.json").exists()   # one simulator stamp per scale
    assert _ran(snakemake(wd, "-n", "--config", "scale=smoke", "build=alt", "scenes=[drift,volume]")) == set()


@pytest.mark.parametrize("override, expected", [
    (["scale=huge"], "unknown scale 'huge'"),
    (["folds={n_folds: two, train_lifts_per_volume: 3, test_lifts_per_volume: 2}"], "folds.n_folds"),
    (["mlpp=1"], "'mlpp' was unexpected"),
    # a recorded session that is not there: named by the session sheet before any job is planned
    (["drift_session=d2026-01-01"], "WorkflowError in file"),
    (["drift_session=d2026-01-01"], "raw/drift/d2026-01-01: session folder not found (params.yaml drift_session)"),
    # a session name is one plain folder name under raw/<study>/, never a way out of it
    (["tool_sessions=[..]"], "invalid parameter at 'tool_sessions.0': '..' is not a plain folder name under raw/<study>/"),
    (["drift_session=../volume"], "invalid parameter at 'drift_session': '../volume' is not a plain folder name"),
])
def test_bad_config_stops_before_any_job(tmp_path: Path, override, expected):
    wd = copy_project(tmp_path)
    proc = snakemake(wd, "-n", "--config", *override, check=False)
    assert proc.returncode != 0
    assert expected in proc.stdout + proc.stderr
    assert not (wd / "results").exists() and not (wd / "raw").exists()


def test_a_billion_laughs_params_file_stops_snakemake_in_one_line(tmp_path: Path):
    """Snakemake itself loads params.yaml (`configfile:`): the Snakefile bounds its aliases first."""
    wd = copy_project(tmp_path)
    (wd / "params.yaml").write_text(billion_laughs())
    proc = subprocess.run([str(BIN / "snakemake"), "-n", "--cores", "2"], cwd=wd, capture_output=True, text=True,
                          timeout=120, env={**ENV, "PYTHONPATH": str(wd / "src")})
    assert proc.returncode == 1
    assert proc.stderr.strip().splitlines() == ["error: params.yaml: its anchors and aliases expand to more than "
                                                "200,000 nodes (at line 6): refused before loading"], proc.stderr


@pytest.mark.extended
def test_dvc_repro_builds_a_scene_from_nothing(tmp_path: Path):
    """`dvc repro <stage>` in a fresh git + DVC project runs the stage and the ones it needs, in
    order, and records them. (The whole graph's `dvc repro` runs in test_dvc_workflow.py, over the
    shared smoke build.)"""
    wd = copy_project(tmp_path, scale="smoke")
    run(["git", "init", "-q"], wd)
    run([str(BIN / "dvc"), "init", "-q"], wd)
    out = run([str(BIN / "dvc"), "repro", "volume"], wd)
    assert re.findall(r"Running stage '(\w+)'", out.stdout + out.stderr) == ["volume_simulate", "volume"]
    m = json.loads((results(wd) / "volume/scores.json").read_text())
    assert m["scale"] == "smoke" and m["r2"]["fy_fz"]["mean"] > 0.9
    shown = json.loads(run([str(BIN / "dvc"), "metrics", "show", "--json"], wd).stdout)
    assert f"{SMOKE}/volume/metrics/baseline.json" in json.dumps(shown)
    status = json.loads(run([str(BIN / "dvc"), "status", "--json", "volume"], wd).stdout or "{}")
    assert status == {}, status
    lock = yaml.safe_load((wd / "dvc.lock").read_text())
    assert set(lock["stages"]) == {"volume_simulate", "volume"}
    assert "mlp" in lock["stages"]["volume"]["params"]["params.yaml"]
    assert not (results(wd) / "tool_normal").exists() and not (wd / "raw/drift").exists()


def test_a_tool_model_trains_and_predicts_through_snakemake(smoke_build: Path):
    target = f"{SMOKE}/tool_normal/models/full/eval.json"     # built by the smoke run (scene tool_normal)
    e = json.loads((smoke_build / target).read_text())
    assert e["variant"] == "full" and e["split"] == "trial"
    assert e["n"] > 0 and e["latency_ms"] > 0
    tt = load_params(smoke_build / "params.yaml")["tool_train"]           # the model the smoke scale asks for
    with torch.device("meta"):
        expected = count_parameters(build_model("full", tt["depth"], tt["image_size"], tt["gam_channel_gate"],
                                                tt["width"]))
    assert e["parameters"] == expected and tt["width"] < PAPER_WIDTH
    assert {"mae", "rmse", "r2", "slope", "intercept", "per_tool", "per_window"} <= set(e)
    assert sum(w["n"] for w in e["per_window"]) == e["n"]        # every test pair counted once
    proc = run([str(BIN / "tactilepipe"), "predict", "--scale", "smoke", "--checkpoint",
                str(results(smoke_build) / "tool_normal/models/full/best.pt"), "--trial",
                str(smoke_build / "raw/tool/sim-smoke/screwdriver_1_p00_normal00"), "--limit", "5"], smoke_build)
    lines = proc.stdout.strip().splitlines()
    assert lines[0] == "pair,left_frame,right_frame,t_s,prediction_n,latency_ms" and len(lines) == 7 and "pairs/s" in lines[-1]


def test_long_jobs_log_their_progress_under_snakemake(smoke_build: Path):
    """Each job's stderr is its log file (no terminal): a training job writes one line per epoch of
    its history, the simulators a count of their recordings, ingest what it read."""
    logs, models = results(smoke_build) / "logs", results(smoke_build) / "tool_normal/models"
    for run_dir in (models / "full", models / "no_ref_r1"):
        epochs = [line.split(",")[0] for line in (run_dir / "history.csv").read_text().splitlines()[1:]]
        log = (logs / f"tool_normal/train_{run_dir.name}.log").read_text()
        lines = [line for line in log.splitlines() if line.startswith("epoch ")]
        assert [re.match(r"epoch (\d+)/\d+: train loss .+, val loss .+, val MAE .+ N, .+ \(elapsed .+ s\)$", line)[1]
                for line in lines] == epochs and epochs, log
    for study in ("volume", "drift", "tool"):
        log = (logs / f"{study}_simulate/sim-smoke.log").read_text()
        assert re.search(rf"^simulate {study}: (\d+)/\1 done \(", log, flags=re.M), log
    ingest = next((logs / "ingest").rglob("*.log")).read_text()
    assert json.loads(ingest.splitlines()[-1])["messages"] > 0


def test_every_figure_of_the_build_has_its_svg_twin(smoke_build: Path):
    pngs = sorted(p for p in results(smoke_build).rglob("*.png") if "/models/" not in str(p))
    assert len(pngs) > 20
    missing = [str(p) for p in pngs if not p.with_suffix(".svg").is_file()]
    assert missing == []
    assert all(p.with_suffix(".svg").read_text().startswith("<?xml") for p in pngs)


def test_names_with_spaces_go_through_the_rules(tmp_path: Path):
    """A session, bag and trial folder named with spaces (as rigs and people name them) are
    ingested: every path reaches the shell quoted, and the logs land where the rules say."""
    (tmp_path / "project").mkdir()
    wd = copy_project(tmp_path / "project", scale="smoke")
    rig = tmp_path / "rig recordings"
    tp = [str(BIN / "tactilepipe")]
    run(tp + ["volume-simulate", "--scale", "smoke", "--out-dir", str(rig / "volume"), "--lifts", "v000_main_l00"], wd)
    run(tp + ["tool-simulate", "--scale", "smoke", "--out-dir", str(rig / "tool"),
              "--trials", "paper_knife_p00_normal00"], wd)
    (wd / "raw/volume/real session").mkdir(parents=True)
    shutil.copy(rig / "volume/v000_main_l00.bag", wd / "raw/volume/real session/lift 0 ml.bag")
    (wd / "raw/tool/real rig").mkdir(parents=True)
    shutil.copy(rig / "tool/nano17.cal", wd / "raw/tool/real rig/nano17.cal")
    shutil.copytree(rig / "tool/paper_knife_p00_normal00", wd / "raw/tool/real rig/Trial 1")
    targets = [f"{SMOKE}/volume/shards/real session/lift 0 ml.parquet", f"{SMOKE}/tool/shards/real rig/Trial 1.parquet"]
    snakemake(wd, *targets)
    for target in targets:
        assert (wd / target).stat().st_size > 0, target
    assert (results(wd) / "logs/ingest/volume/real session/lift 0 ml.log").exists()
    assert (results(wd) / "logs/tool_ingest/real rig/Trial 1.log").exists()
    stray = [p.name for p in (results(wd) / "logs").rglob("*") if p.is_file() and p.name in ("0", "ml.log", "1.log")]
    assert stray == []


def _ran(proc) -> set[str]:
    """The rules whose jobs a Snakemake run (or dry run) printed, `all` left out."""
    return set(re.findall(r"^(?:local)?rule (\w+):$", proc.stdout + proc.stderr, flags=re.M)) - {"all"}


def test_each_scale_keeps_its_own_results_and_a_round_trip_reruns_nothing(smoke_build: Path, tmp_path: Path):
    """Two smoke-sized overlays (the second simulates the container faster, so its volume data and
    everything after differ), each building under its own results/<scale>/: a dry run of the other
    leaves git clean; a build of the other changes no tracked file, neither the first's results nor
    the committed default scale's; back at the first, nothing is planned and its numbers are the
    same bytes. A named build of the same scale plans its own results beside them."""
    wd = shutil.copytree(smoke_build, tmp_path / "wd", symlinks=True)
    shutil.copy(REPO / ".gitignore", wd / ".gitignore")
    for name in run(["git", "ls-files", "results/default"], REPO).stdout.split():   # the committed default scale
        (wd / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / name, wd / name)
    assert (results(wd, "default") / "volume/metrics/fy_fz.json").is_file()
    params = yaml.safe_load((wd / "params.yaml").read_text())
    other = {**params["scales"]["smoke"]}
    other["simulate_volume"] = {**other["simulate_volume"], "rate_hz": 250}
    params["scales"]["smoke_b"] = other
    (wd / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))
    for cmd in (["init", "-q"], ["add", "-A"], ["-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "built"]):
        run(["git", *cmd], wd)
    tracked = run(["git", "ls-files", "results"], wd).stdout.split()
    assert f"{SMOKE}/volume/metrics/fy_fz.json" in tracked and f"{SMOKE}/params/volume-report.json" in tracked
    assert f"{SMOKE}/params/tool-train/full.json" in tracked          # a training job's own stamp too
    before = (results(wd) / "volume/metrics/fy_fz.json").read_bytes()
    volume = ["--config", "scenes=[volume]"]

    dry = snakemake(wd, "-n", *volume, "scale=smoke_b")
    assert {"volume_simulate", "volume_dataset", "volume_report"} <= _ran(dry)
    assert "changed-params/volume-simulate.json" in dry.stdout + dry.stderr     # the reason names the stamp
    assert run(["git", "status", "--porcelain"], wd).stdout == ""
    assert _ran(snakemake(wd, "-n", *volume, "scale=smoke")) == set()

    there = snakemake(wd, *volume, "scale=smoke_b")
    assert {"volume_simulate", "papillarray_ingest", "volume_report"} <= _ran(there)
    assert (results(wd, "smoke_b") / "volume/metrics/fy_fz.json").read_bytes() != before
    status = run(["git", "status", "--porcelain", "--untracked-files=all"], wd).stdout.splitlines()
    assert status and all(line.startswith("?? results/smoke_b/") for line in status), status
    assert _ran(snakemake(wd, "-n", *volume, "scale=smoke")) == set()
    assert (results(wd) / "volume/metrics/fy_fz.json").read_bytes() == before

    named = snakemake(wd, "-n", *volume, "scale=smoke", "build=smoke_real_only")   # same recordings, own results
    assert {"papillarray_ingest", "volume_report"} <= _ran(named) and "volume_simulate" not in _ran(named)
    assert "results/smoke_real_only/volume/metrics/fy_fz.json" in named.stdout
    assert run(["git", "status", "--porcelain"], wd).stdout == "?? results/smoke_b/\n"


TOOL_SCENES = ("tool_normal", "tool_shear")
UPSTREAM_OF_TRAINING = {"tool_simulate", "tool_ingest", "tool_clock_figure", "tool_dataset", "tool_split",
                        "tool_data_report"}


def _planned_jobs(proc) -> set[tuple[str, str]]:
    """(rule, wildcards) of every job a dry run printed, `all` left out."""
    text = proc.stdout + proc.stderr
    jobs = re.findall(r"^(?:local)?rule (\w+):\n((?:    .*\n)*)", text, flags=re.M)
    out = set()
    for rule, body in jobs:
        wildcards = re.search(r"^    wildcards: (.*)$", body, flags=re.M)
        out.add((rule, wildcards.group(1) if wildcards else ""))
    return out - {("all", "")}


def _trainings(scenes, runs) -> set[tuple[str, str]]:
    return {("tool_train", f"scene={s}, run={r}") for s in scenes for r in runs}


def _with_variant_copy(params: Path, source: str, name: str) -> None:
    """params.yaml with one more entry in tool_variants: a copy of ``source``'s under ``name``."""
    text = params.read_text()
    start = text.index(f"\n  {source}:\n") + 1
    end = text.index("\ntool_train:", start)
    entry = text[start:end].rstrip("\n").replace(f"  {source}:", f"  {name}:", 1)
    params.unlink()                                      # a file of its own, not a link into the shared build
    params.write_text(text[:end].rstrip("\n") + "\n" + entry + "\n" + text[end:])


def test_a_new_model_variant_is_one_entry_in_params_yaml_and_trains_only_its_own_runs(smoke_build: Path,
                                                                                       tmp_path: Path):
    """A variant is data: one more entry in params.yaml plans its runs (every repeat, both tool
    scenes) and the two model reports, nothing upstream and no other run; dvc.yaml is still what its
    generator makes; trained, the report scores it against its like-for-like baseline."""
    wd = shutil.copytree(smoke_build, tmp_path / "wd", symlinks=True)
    _with_variant_copy(wd / "params.yaml", "no_gam", "no_gam_copy")
    planned = _planned_jobs(snakemake(wd, "-n", "--config", "scale=smoke"))
    assert planned == _trainings(TOOL_SCENES, ["no_gam_copy", "no_gam_copy_r1"]) | \
        {("tool_model_report", f"scene={s}") for s in TOOL_SCENES}, planned
    assert run([str(BIN / "python"), "workflow/scripts/dvc_yaml.py", "--check"], wd).returncode == 0
    assert "tool_variants" in yaml.safe_load((wd / "dvc.yaml").read_text())["stages"]["tool_models"]["params"]
    before = run_digests(results(wd))
    snakemake(wd, f"{SMOKE}/tool_normal/metrics/full.json", "--config", "scale=smoke", "scenes=[tool_normal]")
    after = run_digests(results(wd))
    assert {r: d for r, d in after.items() if "no_gam_copy" not in r} == before          # none trained again
    stamp = json.loads((results(wd) / "params/tool-train/no_gam_copy_r1.json").read_text())
    assert stamp["values"]["run"]["variant"] == {"name": "no_gam_copy", "sensors": [[0, 2], [2, 4]], "gam": False}
    metrics = json.loads((results(wd) / "tool_normal/scores.json").read_text())
    new = metrics["no_gam_copy"]
    assert new["like_for_like_baseline"] == "tactile_rmse_linear" and new["over_splits"]["mae"]["n"] == 2
    assert "| no_gam_copy |" in (results(wd) / "tool_normal/tables/variants.md").read_text()


def test_a_training_key_re_runs_exactly_the_runs_that_read_it(smoke_build: Path, tmp_path: Path):
    """Each training job has its own stamp: tool_train.image_size, which the sweep runs do not read,
    plans every run but those; tool_train.lr plans every run. Neither plans anything upstream."""
    wd = linked_copy(smoke_build, tmp_path / "wd")       # dry runs only
    p = load_params(wd / "params.yaml", {"scale": "smoke"})
    every = tool_runs(p["tool_train"], p["tool_split"]["repeats"], p["simulate_tool"]["tools_used"])
    sweep = {sweep_run_name(s) for s in p["tool_train"]["sweep"]}
    assert sweep and sweep < set(every)
    reports = {("tool_model_report", f"scene={s}") for s in TOOL_SCENES}
    sized = _planned_jobs(snakemake(wd, "-n", "--config", "scale=smoke", 'tool_train={"image_size": 12}'))
    assert sized == _trainings(TOOL_SCENES, set(every) - sweep) | reports, sized
    faster = _planned_jobs(snakemake(wd, "-n", "--config", "scale=smoke", 'tool_train={"lr": 0.001}'))
    assert faster == _trainings(TOOL_SCENES, every) | reports, faster
    assert not {rule for rule, _w in sized | faster} & UPSTREAM_OF_TRAINING
    assert "Nothing to be done" in snakemake(wd, "-n", "--config", "scale=smoke").stdout   # the dry runs wrote no stamp


# A new training setting, as a user adds one: its value, its typed field, the line that uses it
NEW_SETTING = {
    "params.yaml": ("\n  lr: 0.0002 ", "\n  weight_decay: 0.01        # Adam's L2 penalty\n  lr: 0.0002 "),
    "src/tactilepipe/core/parameters/training.py": (
        "\n    lr: float = Field(",
        "\n    weight_decay: float = Field(ge=0, le=1, description=\"Adam's L2 penalty\")\n    lr: float = Field("),
    "src/tactilepipe/tool/model/train.py": (
        "        opt = make_optimizer(model, cfg.lr)\n",
        "        opt = make_optimizer(model, cfg.lr)\n        opt.param_groups[0][\"weight_decay\"] = cfg.weight_decay\n"),
}


def _replace_in_copy(path: Path, old: str, new: str) -> None:
    """Replace ``old`` (once) in a file of a copied project, as a file of its own."""
    text = path.read_text()
    assert text.count(old) == 1, (path, old)
    path.unlink()
    path.write_text(text.replace(old, new))


def test_a_new_training_setting_is_three_files_and_re_runs_only_the_trainings(smoke_build: Path, tmp_path: Path):
    """A training setting is its value in params.yaml, its field in the typed settings and the line
    of training that reads it (the schema is generated): nothing in the stage's declaration, its
    configuration or the rules. Snakemake plans every training and the two model reports, nothing
    upstream; dvc.yaml needs no change; trained, the run's stamp and checkpoint hold the value and
    its weights differ from the build's."""
    wd = shutil.copytree(smoke_build, tmp_path / "wd", symlinks=True)
    for name, (old, new) in NEW_SETTING.items():
        _replace_in_copy(wd / name, old, new)
    run([str(BIN / "python"), "workflow/scripts/params_schema.py"], wd)       # generated, not written by hand
    p = load_params(smoke_build / "params.yaml", {"scale": "smoke"})     # the runs are the build's
    every = tool_runs(p["tool_train"], p["tool_split"]["repeats"], p["simulate_tool"]["tools_used"])
    planned = _planned_jobs(snakemake(wd, "-n", "--config", "scale=smoke"))
    assert planned == _trainings(TOOL_SCENES, every) | {("tool_model_report", f"scene={s}") for s in TOOL_SCENES}, \
        planned
    assert run([str(BIN / "python"), "workflow/scripts/dvc_yaml.py", "--check"], wd).returncode == 0
    before = run_digests(results(wd))["tool_normal/full"]
    snakemake(wd, f"{SMOKE}/tool_normal/models/full/eval.json", "--config", "scale=smoke", "scenes=[tool_normal]")
    stamp = json.loads((results(wd) / "params/tool-train/full.json").read_text())
    assert stamp["values"]["tool_train"]["weight_decay"] == 0.01
    checkpoint = load_checkpoint(results(wd) / "tool_normal/models/full/best.pt")
    assert checkpoint["config"]["weight_decay"] == 0.01
    assert run_digests(results(wd))["tool_normal/full"]["weights"] != before["weights"]


def test_a_simulator_key_re_runs_only_the_scenes_that_simulate_with_it(smoke_build: Path, tmp_path: Path):
    """simulate_volume describes the lift rig and its sensor: a key of the lift (the grip's
    repeatability) plans the volume scene again and nothing of the drift or tool scenes; a key of
    the sensor (its noise), which the drift simulator reads too, plans both, and no tool job."""
    wd = linked_copy(smoke_build, tmp_path / "wd")       # dry runs only
    lift = _planned_jobs(snakemake(wd, "-n", "--config", "scale=smoke", 'simulate_volume={"grip_force_rel_std": 0.05}'))
    rules = {rule for rule, _w in lift}
    assert {"volume_simulate", "papillarray_ingest", "volume_dataset", "volume_report"} <= rules, rules
    assert not any(rule.startswith(("drift_", "tool_")) for rule in rules), rules
    assert all(w.startswith("scene=volume,") for rule, w in lift if rule == "papillarray_ingest")
    sensor = {rule for rule, _w in _planned_jobs(snakemake(wd, "-n", "--config", "scale=smoke",
                                                           'simulate_volume={"noise_std_n": 0.02}'))}
    assert {"volume_simulate", "drift_simulate", "drift_report", "volume_report"} <= sensor, sensor
    assert not any(rule.startswith("tool_") for rule in sensor), sensor
    assert "Nothing to be done" in snakemake(wd, "-n", "--config", "scale=smoke").stdout   # the dry runs wrote no stamp


def _edit_copy(path: Path, text: str) -> None:
    """Append ``text`` to a file of a linked copy, as a file of its own (the build keeps its own)."""
    old = path.read_text()
    path.unlink()
    path.write_text(old + text)


def test_an_edit_in_one_studys_code_plans_no_job_of_the_other(smoke_build: Path, tmp_path: Path):
    """A stage's code is what its function runs: an edit inside the volume study's code plans
    volume jobs only, one inside the tool study's code tool jobs only."""
    planned = {}
    for study, path in [("volume", "volume/mlp.py"), ("tool", "tool/model/network.py")]:
        wd = linked_copy(smoke_build, tmp_path / study)       # dry runs only
        _edit_copy(wd / "src/tactilepipe" / path, "# edited\n")
        planned[study] = {rule for rule, _w in _planned_jobs(snakemake(wd, "-n", "--config", "scale=smoke"))}
    assert planned["volume"] and all(rule.startswith("volume_") for rule in planned["volume"]), planned
    assert planned["tool"] and all(rule.startswith("tool_") for rule in planned["tool"]), planned


NEW_STAGE = '''"""A count of the volume data set's lifts, and a figure of them per volume."""

from tactilepipe.cli.registry import arg, command
from tactilepipe.cli.volume_args import VOLUME_CHECKS


@command("volume-summary", "lifts and volumes of the dataset, counted and drawn",
         checks=VOLUME_CHECKS, params=("seed",),
         args=(arg("--dataset", required=True), arg("--out", required=True), arg("--figure", required=True)),
         rule={"scene": "volume", "inputs": {"dataset": "volume/dataset.parquet"},
               "outputs": {"out": "volume/summary.json", "figure": "volume/figures/lifts_per_volume.png"},
               "report": {"figure": "Lifts per volume"}})
def cmd_volume_summary(args, p) -> None:
    import pandas as pd
    from tactilepipe.core.atomic import write_json
    from tactilepipe.core.plotting import plt
    data = pd.read_parquet(args.dataset).drop_duplicates("lift")
    write_json(args.out, {"lifts": len(data), "volumes_ml": sorted(set(data["volume_ml"].tolist()))})
    counts = data["volume_ml"].value_counts().sort_index()
    fig, ax = plt.subplots()
    ax.bar([str(v) for v in counts.index], counts.values)
    ax.set(xlabel="volume (ml)", ylabel="lifts")
    fig.savefig(args.figure, dpi=80)
'''
CAPTION = "Lifts of each volume in the data set, scale ``{{ snakemake.config.scale }}``.\n"


def test_a_new_stage_with_a_figure_is_its_module_its_caption_and_nothing_else(smoke_build: Path, tmp_path: Path):
    """A stage that declares its rule needs no rule file, target list, command list, report entry
    or DVC stage written for it: its module and its figure's caption added, Snakemake plans its job
    and the scene's report (whose provenance.json now records the stage), its figure is an item of
    `snakemake --report` with its label and caption, the regenerated dvc.yaml holds it in the
    scene's stage, and `dvc repro` builds it. Without its caption the workflow stops, naming it."""
    wd = shutil.copytree(smoke_build, tmp_path / "wd", symlinks=True)
    params = wd / "params.yaml"
    params.write_text(re.sub(r"^scale: \w+", "scale: smoke", params.read_text(), count=1, flags=re.M))
    (wd / "src/tactilepipe/cli/volume_summary.py").write_text(NEW_STAGE)      # the stage's one file of code
    caption = wd / "workflow/report/volume/lifts_per_volume.rst"
    proc = snakemake(wd, "-n", check=False)
    assert proc.returncode != 0 and "needs its caption, workflow/report/volume/lifts_per_volume.rst" in \
        proc.stdout + proc.stderr, proc.stderr[-2000:]
    caption.write_text(CAPTION)                                                # and its caption
    planned = _planned_jobs(snakemake(wd, "-n"))
    assert planned == {("volume_summary", ""), ("volume_report", "")}, planned
    snakemake(wd)
    summary = json.loads((results(wd) / "volume/summary.json").read_text())
    assert summary["lifts"] > 0 and 0.0 in summary["volumes_ml"]
    assert (results(wd) / "volume/figures/lifts_per_volume.png").read_bytes()[:4] == b"\x89PNG"
    assert (results(wd) / "logs/volume/volume_summary.log").exists()
    provenance = json.loads((results(wd) / "volume/provenance.json").read_text())
    assert provenance["stages"]["volume-summary"]["params"] == {"seed": load_params(wd / "params.yaml")["seed"]}
    assert len(provenance["stages"]["volume-summary"]["code_sha256"]) == 64
    html = tmp_path / "report.html"
    snakemake(wd, "--report", str(html))
    line = next(l for l in html.read_text().splitlines() if l.strip().startswith("var results = {"))
    items = json.loads(line.strip()[len("var results = "):].rstrip(";"))
    item = next(v for k, v in items.items() if k.endswith("volume/figures/lifts_per_volume.png"))
    assert item["labels"] == {"result": "Lifts per volume"} and "Lifts of each volume" in item["caption"], item
    assert "scale smoke" in re.sub(r"<[^>]+>", "", item["caption"]).replace("``", ""), item["caption"]
    run([str(BIN / "python"), "workflow/scripts/dvc_yaml.py"], wd)
    stage = yaml.safe_load((wd / "dvc.yaml").read_text())["stages"]["volume"]
    assert "results/${scale}/volume/summary.json" in json.dumps(stage["outs"]), stage["outs"]
    assert "src/tactilepipe/cli/volume_summary.py" in stage["deps"] and "seed" in stage["params"]
    run(["git", "init", "-q"], wd)
    run([str(BIN / "dvc"), "init", "-q"], wd)
    (results(wd) / "volume/summary.json").unlink()
    out = run([str(BIN / "dvc"), "repro", "volume"], wd)
    assert "Running stage 'volume'" in out.stdout + out.stderr
    assert json.loads((results(wd) / "volume/summary.json").read_text()) == summary
    assert "volume_summary" in out.stdout + out.stderr                     # Snakemake inside ran exactly it
    status = json.loads(run([str(BIN / "dvc"), "status", "--json", "volume"], wd).stdout or "{}")
    assert status == {}, status


# --- one checkout, one code ----------------------------------------------------------------------

def _without_pythonpath(**extra: str) -> dict:
    return {**{k: v for k, v in ENV.items() if k != "PYTHONPATH"}, **extra}


def test_a_copy_run_with_the_other_checkouts_venv_stops_snakemake_in_one_line(tmp_path: Path):
    """A copy of the project beside this one, run with this checkout's venv (whose editable install
    imports this checkout's src/), would plan and track this checkout's code: it stops instead,
    naming both folders. Given its own code (PYTHONPATH), the same copy plans its jobs."""
    import tactilepipe
    wd = copy_project(tmp_path)
    imported = Path(tactilepipe.__file__).resolve().parent
    assert imported != (wd / "src" / "tactilepipe").resolve()
    dry = [str(BIN / "snakemake"), "-n", "--cores", "2"]
    proc = subprocess.run(dry, cwd=wd, capture_output=True, text=True, timeout=120, env=_without_pythonpath())
    assert proc.returncode != 0
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    assert f"{(wd / 'src' / 'tactilepipe').resolve()}," in lines[0] and f"from {imported}:" in lines[0], lines[0]
    assert "jobs" not in proc.stdout, proc.stdout[-2000:]
    own = subprocess.run(dry, cwd=wd, capture_output=True, text=True, timeout=300,
                         env=_without_pythonpath(PYTHONPATH=str(wd / "src")))
    assert own.returncode == 0 and "error: " not in own.stderr, own.stderr[-2000:]


def _version(wd: Path) -> str:
    # run from outside the checkout: the commit is that of the package's checkout, not of the folder
    proc = subprocess.run([str(BIN / "tactilepipe"), "--version"], cwd=wd.parent, capture_output=True, text=True,
                          timeout=60, env=_without_pythonpath(PYTHONPATH=str(wd / "src")))
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    return proc.stdout.strip()


def test_version_names_the_commit_of_the_checkout_the_code_is_imported_from(tmp_path: Path):
    wd = tmp_path / "copy"
    wd.mkdir()
    copy_project(wd)
    shutil.copy(REPO / ".gitignore", wd / ".gitignore")     # Python's bytecode caches are not changes
    package = (wd / "src" / "tactilepipe").resolve()
    assert _version(wd) == f"tactilepipe 0.1.0 (not in a git checkout) from {package}"
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@example.org"]
    for args in (["init", "-q"], ["add", "-A"], ["commit", "-q", "-m", "copy"]):
        subprocess.run([*git, *args], cwd=wd, check=True, capture_output=True)
    commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=wd, capture_output=True, text=True).stdout.strip()
    assert _version(wd) == f"tactilepipe 0.1.0 (commit {commit[:12]}) from {package}"
    with open(wd / "src" / "tactilepipe" / "pipeline" / "scenes.py", "a") as f:
        f.write("# an edit not committed\n")
    assert _version(wd) == f"tactilepipe 0.1.0 (commit {commit[:12]}, modified) from {package}"
