"""Day-to-day DVC work, end to end with the real `git`, `dvc` and `snakemake` command lines, in a
temporary git repository with a local-directory remote, at the smoke scale:

1. a new recording session: `dvc add`, `dvc repro` re-runs only the volume stage and ingests only
   the new bags; `dvc metrics diff` shows the change against the last commit; the same for a new
   tool-rig session (only tool_data and tool_models re-run, only the new trials are ingested) and
   for a new drift experiment (only the drift stage re-runs);
2. experiments: `dvc exp run -S ...`, `dvc exp show --md`, `dvc exp diff`, `dvc params diff`;
3. sharing: `dvc push`, a fresh `git clone` + `dvc pull` is byte-identical and Snakemake has
   nothing to do;
4. plots: `dvc plots show` (offline) and `dvc plots diff` between two commits.
(`snakemake --report`: tests/integration/test_report.py.)

`make test` (CI) runs the volume and drift sessions, sharing, plots and code edits; the tool
session, the experiments, `tactilepipe diff` on a retrained build and the clone checks that each
retrain models or pull a whole clone again are `extended` (`make test-all`)."""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

import pytest
import yaml

from support.dvc_graph import covers, dvc_stages
from support.project import BIN, REPO, SMOKE, copy_project, dvc, git, results, run, snakemake
from tactilepipe.tool.scenes import TOOL_SCENES

pytestmark = pytest.mark.integration

STAGES = ["volume_simulate", "drift_simulate", "volume", "drift", "tool_simulate", "tool_data", "tool_models"]
NEW = "s2026-05-01"        # the "new recording session"
NEW_TOOL = "t2026-05-02"   # a new tool-rig session (native layout, like real recordings)
NEW_DRIFT = "d2026-05-03"  # a new drift experiment (bags named {unloaded,loaded}_tMM.bag)
VARIANTS = "[full, no_ref]"                           # this project's (params.yaml trains all)


def dvc_out(wd: Path, *args: str) -> str:
    """stdout + stderr (Snakemake's job lines and stats reach dvc's stderr)."""
    proc = dvc(wd, *args)
    return proc.stdout + proc.stderr


def ran_stages(out: str) -> set[str]:
    return set(re.findall(r"Running stage '(\w+)'", out))


def job_counts(out: str) -> dict[str, int]:
    """Snakemake's "Job stats" tables in a command's output, summed over runs."""
    counts: dict[str, int] = {}
    for rule, n in re.findall(r"^(\w+)\s+(\d+)$", out, flags=re.M):
        if rule != "total":
            counts[rule] = counts.get(rule, 0) + int(n)
    return counts


TARGET_RULES = {"all", "volume", "drift", "tool_data", "tool_normal", "tool_shear"}   # rules that only name files


def work(counts: dict[str, int]) -> dict[str, int]:
    """The jobs that do work: `snakemake -n` plans the default target `all`, a DVC stage its scene's rule."""
    return {rule: n for rule, n in counts.items() if rule not in TARGET_RULES}


def tracked_files(wd: Path) -> dict[str, bytes]:
    """Every file under raw/ and results/ (the logs and the resume checkpoints last.pt are not
    artefacts: not tracked, not shared)."""
    return {str(p.relative_to(wd)): p.read_bytes() for top in ("raw", "results") for p in sorted((wd / top).rglob("*"))
            if p.is_file() and not str(p.relative_to(wd)).startswith((f"{SMOKE}/logs/", f"{SMOKE}/params/"))
            and p.name not in (".gitignore", "README.md", "last.pt") and p.suffix != ".dvc"}   # last.pt: .dvcignore


@pytest.fixture(scope="module")
def repo(tmp_path_factory) -> dict:
    """A git + DVC project at the smoke scale, reproduced, committed and pushed to a local remote.
    As a user would: the pipeline is built with Snakemake (`make run`), which records what it built
    for DVC (dvc.lock and the cache), then committed and pushed. The project is this module's own (not
    the shared smoke build): so `make test` can run it on one worker while the shared build and
    its readers run on the other."""
    root = tmp_path_factory.mktemp("dvcflow")
    wd = root / "project"
    wd.mkdir()
    copy_project(wd, scale="smoke")
    shutil.copy(REPO / ".gitignore", wd / ".gitignore")
    # two of the four model variants on the two repeats, no leave-one-tool-out and no sweep runs:
    # the new tool session and the learning-rate experiment below retrain every run of the tool
    # scenes, and these 8 show it (the smoke build trains the others: test_workflow.py). dvc.yaml
    # is generated again for these parameters (`make dvc.yaml`): without loto, no loto figure
    params = (wd / "params.yaml").read_text()
    for pattern, line in ((r"^  variants: all .*$", f"  variants: {VARIANTS}"), (r"^  loto: true ", "  loto: false "),
                          (r"sweep: \[\{depth: 18, image_size: 8\}\]", "sweep: []")):
        assert len(re.findall(pattern, params, flags=re.M)) == 1, pattern
        params = re.sub(pattern, line, params, flags=re.M)
    (wd / "params.yaml").write_text(params)
    run([str(BIN / "python"), "workflow/scripts/dvc_yaml.py"], wd)
    assert "loto.png" not in (wd / "dvc.yaml").read_text()
    git(wd, "init", "-q")
    git(wd, "config", "user.email", "test@example.com")
    git(wd, "config", "user.name", "test")
    dvc(wd, "init", "-q")
    shutil.copy(REPO / ".dvc/config", wd / ".dvc/config")            # the project's cache and remote set-up
    remote = root / "remote"
    dvc(wd, "remote", "modify", "local", "url", str(remote))        # committed: a clone finds it
    # the build with Snakemake (`make run`) records every stage it made for DVC, as `dvc commit`
    # does: one state for both tools, so DVC plans nothing of what Snakemake built
    proc = snakemake(wd, "--workflow-profile", "workflow/profiles/default")
    assert f"DVC: recorded {len(STAGES)} stage(s)" in proc.stderr, proc.stderr[-3000:]
    assert "up to date" in dvc(wd, "status").stdout.lower()
    out = dvc_out(wd, "repro", "--dry")
    assert ran_stages(out) == set() and "Data and pipelines are up to date" in out, out[-3000:]
    proc = snakemake(wd, "-n")
    assert "Nothing to be done" in proc.stdout + proc.stderr, proc.stdout[-3000:]
    git(wd, "add", ".")
    git(wd, "commit", "-q", "-m", "baseline at smoke scale")
    dvc(wd, "push")
    baseline = {"lock": yaml.safe_load((wd / "dvc.lock").read_text()),
                "metrics": json.loads(dvc(wd, "metrics", "show", "--json").stdout)}
    yield {"wd": wd, "root": root, "remote": remote, "baseline": baseline}
    shutil.rmtree(root, ignore_errors=True)          # the project, its clones and the remote


def test_every_generated_file_is_a_declared_out(repo):
    wd = repo["wd"]
    assert "up to date" in dvc(wd, "status").stdout.lower()
    outs = [o for s in dvc_stages(wd / "dvc.yaml", yaml.safe_load((wd / "params.yaml").read_text())).values()
            for o in s["outs"]]
    undeclared = [f for f in tracked_files(wd) if not any(covers(f, o) for o in outs)]
    assert undeclared == []
    # metrics are `cache: false`: git versions them (a clone has them without a pull)
    in_git = run(["git", "ls-files", "results"], wd).stdout.split()
    assert sorted(f for f in in_git if "/metrics/" in f) == sorted(
        [f"{SMOKE}/drift/metrics/{r}.json" for r in ("loaded", "unloaded")]
        + [f"{SMOKE}/{s}/metrics/{v}.json" for s in ("tool_normal", "tool_shear") for v in ("full", "no_ref")]
        + [f"{SMOKE}/volume/metrics/{m}.json" for m in ("baseline", "fx_fy_fz", "fy", "fy_fz", "fz")])
    assert (wd / ".dvc/config").read_text().count("reflink,copy") == 1


def test_dvc_repro_records_every_stage_and_its_metrics(repo):
    lock = repo["baseline"]["lock"]
    assert set(lock["stages"]) == set(STAGES)
    assert "mlp" in lock["stages"]["volume"]["params"]["params.yaml"]
    assert lock["stages"]["tool_models"]["params"]["params.yaml"]["scale"] == "smoke"
    shown = json.dumps(repo["baseline"]["metrics"])
    for scene in ("volume", "drift", "tool_normal", "tool_shear"):
        assert f"{SMOKE}/{scene}/metrics/" in shown, scene
    volume = json.loads((results(repo["wd"]) / "volume/scores.json").read_text())
    assert volume["scale"] == "smoke" and volume["r2"]["fy_fz"]["mean"] > 0.9


def take_in_session(repo: dict, scene: str, session: str, simulate_flags: list[str], param_line: str,
                    new_param_line: str, scene_dirs: list[str]) -> dict:
    """A session "recorded on the rig" (the simulator with another seed, somewhere else) is copied
    into raw/<scene>/, `dvc add`ed, named in params.yaml, reproduced, committed and pushed.
    Returns dvc repro's output and the metrics diff (JSON and Markdown) against the last commit."""
    wd, rig = repo["wd"], repo["root"] / "rig"
    run([str(BIN / "tactilepipe"), f"{scene}-simulate", "--scale", "smoke", "--override", '{"seed": 7}',
         "--out-dir", str(rig / session), *simulate_flags, "--jobs", "2"], wd)
    shutil.copytree(rig / session, wd / "raw" / scene / session)
    dvc(wd, "add", f"raw/{scene}/{session}")
    params = (wd / "params.yaml").read_text()
    assert param_line in params
    (wd / "params.yaml").write_text(params.replace(param_line, new_param_line))
    planned = snakemake(wd, "-n", "--workflow-profile", "workflow/profiles/default")   # as DVC's stages run it
    planned_stages = ran_stages(dvc_out(wd, "repro", "--dry"))
    out = dvc_out(wd, "repro")
    # a dry run prints its job stats twice (before and after the job list): the first table is the plan
    plan = (planned.stdout + planned.stderr).split("Job stats:")[1]
    taken = {"out": out, "planned": job_counts(plan), "planned_stages": planned_stages,
             "diff": json.loads(dvc(wd, "metrics", "diff", "--json").stdout),
             "diff_md": dvc(wd, "metrics", "diff", "--md").stdout}
    # each scene's metrics travel with its scores, provenance and run times, and the rules' parameter stamps
    records = [f"{d}/{n}" for d in scene_dirs for n in ("metrics", "scores.json", "provenance.json", "runtime.json")
               if (wd / d / n).exists()]
    git(wd, "add", "params.yaml", "dvc.lock", f"raw/{scene}/{session}.dvc", f"raw/{scene}/.gitignore", *records,
        f"{SMOKE}/params")
    git(wd, "commit", "-q", "-m", f"new {scene} session {session}")
    dvc(wd, "push")
    return taken


@pytest.fixture(scope="module")
def new_session(repo) -> dict:
    """Step 1: a new volume session recorded elsewhere is copied in, versioned and reproduced."""
    wd = repo["wd"]
    shard_dir = results(wd) / "volume/shards/sim-smoke"
    old_shards = {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in shard_dir.glob("*.parquet")}
    taken = take_in_session(repo, "volume", NEW, ["--labels"], 'volume_sessions: ["sim-{scale}"]',
                            f'volume_sessions: ["sim-{{scale}}", "{NEW}"]', [f"{SMOKE}/volume"])
    n_new = len(list((wd / "raw/volume" / NEW).glob("*.bag")))
    return {**taken, "old_shards": old_shards, "n_new": n_new}


def test_new_session_reruns_only_the_volume_stage_and_ingests_only_new_bags(repo, new_session):
    wd, out = repo["wd"], new_session["out"]
    assert ran_stages(out) == {"volume"} == new_session["planned_stages"], out[-3000:]
    # both tools plan the same work: the jobs `snakemake -n` planned are the jobs `dvc repro` ran
    assert work(job_counts(out)) == work(new_session["planned"]), (job_counts(out), new_session["planned"])
    for stage in set(STAGES) - {"volume"}:
        assert f"Stage '{stage}' didn't change, skipping" in out, stage
    counts = job_counts(out)
    assert new_session["n_new"] > 30
    assert counts["papillarray_ingest"] == new_session["n_new"], counts       # only the new bags
    assert counts["volume_dataset"] == 1 and "volume_simulate" not in counts
    for name, (mtime, data) in new_session["old_shards"].items():             # earlier shards untouched
        p = results(wd) / "volume/shards/sim-smoke" / name
        assert p.stat().st_mtime_ns == mtime and p.read_bytes() == data, name
    assert len(list((results(wd) / f"volume/shards/{NEW}").glob("*.parquet"))) == new_session["n_new"]
    # the metrics diff against the last commit: the volume scene changed, nothing else; and it
    # lists metrics only, not what made them (provenance) nor how long it took (run times)
    diff = new_session["diff"]
    assert diff and all(f.startswith(f"{SMOKE}/volume/metrics/") for f in diff), diff
    assert not [k for f in diff for k in diff[f] if "sessions" in k or "stages" in k], diff
    changed = diff[f"{SMOKE}/volume/metrics/fy_fz.json"]
    assert "r2" in changed and changed["r2"]["old"] != changed["r2"]["new"]
    assert "volume/metrics/fy_fz.json" in new_session["diff_md"] and "HEAD" in new_session["diff_md"]
    assert "up to date" in dvc(wd, "status").stdout.lower()


@pytest.fixture(scope="module")
def new_tool_session(repo, new_session) -> dict:
    """Step 1 for the tool scenes: a new session of the DIGIT + Nano17 rig (its native layout:
    frames, serial log, meta.json per trial, nano17.cal) is copied in, versioned and reproduced."""
    wd = repo["wd"]
    shard_dir = results(wd) / "tool/shards/sim-smoke"
    old_shards = {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in shard_dir.glob("*.parquet")}
    taken = take_in_session(repo, "tool", NEW_TOOL, [], 'tool_sessions: ["sim-{scale}"]',
                            f'tool_sessions: ["sim-{{scale}}", "{NEW_TOOL}"]',
                            [f"{SMOKE}/tool_normal", f"{SMOKE}/tool_shear"])
    n_new = len(list((wd / "raw/tool" / NEW_TOOL).glob("*/meta.json")))
    return {**taken, "old_shards": old_shards, "n_new": n_new}


@pytest.mark.extended
def test_new_tool_session_reruns_only_the_tool_stages_and_ingests_only_new_trials(repo, new_tool_session):
    wd, out = repo["wd"], new_tool_session["out"]
    assert ran_stages(out) == {"tool_data", "tool_models"} == new_tool_session["planned_stages"], out[-3000:]
    assert work(job_counts(out)) == work(new_tool_session["planned"]), (job_counts(out), new_tool_session["planned"])
    for stage in set(STAGES) - {"tool_data", "tool_models"}:
        assert f"Stage '{stage}' didn't change, skipping" in out, stage
    counts = job_counts(out)
    assert new_tool_session["n_new"] >= 12
    assert counts["tool_ingest"] == new_tool_session["n_new"], counts          # only the new trials
    # every run of both scenes: 2 variants x 2 repeats
    assert counts["tool_dataset"] == 2 and counts["tool_train"] == 2 * 2 * 2 and "tool_simulate" not in counts
    for name, (mtime, data) in new_tool_session["old_shards"].items():         # earlier shards untouched
        p = results(wd) / "tool/shards/sim-smoke" / name
        assert p.stat().st_mtime_ns == mtime and p.read_bytes() == data, name
    assert len(list((results(wd) / f"tool/shards/{NEW_TOOL}").glob("*.parquet"))) == new_tool_session["n_new"]
    # the metrics diff against the last commit: both tool scenes changed, nothing else
    diff = new_tool_session["diff"]
    assert {f.split("/")[2] for f in diff} == {"tool_normal", "tool_shear"}, diff
    assert "mae" in diff[f"{SMOKE}/tool_normal/metrics/full.json"], diff
    assert "up to date" in dvc(wd, "status").stdout.lower()


@pytest.fixture(scope="module")
def new_drift_session(repo, new_session) -> dict:
    """Step 1 for the drift scene: a new 30-min drift experiment is copied in and analysed instead
    of the simulated one."""
    taken = take_in_session(repo, "drift", NEW_DRIFT, [], 'drift_session: "sim-{scale}"',
                            f'drift_session: "{NEW_DRIFT}"', [f"{SMOKE}/drift"])
    n_new = len(list((repo["wd"] / "raw/drift" / NEW_DRIFT).glob("*.bag")))
    return {**taken, "n_new": n_new}


def test_new_drift_session_reruns_only_the_drift_stage(repo, new_drift_session):
    wd, out = repo["wd"], new_drift_session["out"]
    assert ran_stages(out) == {"drift"} == new_drift_session["planned_stages"], out[-3000:]
    assert work(job_counts(out)) == work(new_drift_session["planned"]), (job_counts(out), new_drift_session["planned"])
    counts = job_counts(out)
    assert new_drift_session["n_new"] >= 7
    assert counts["papillarray_ingest"] == new_drift_session["n_new"], counts
    assert counts["drift_report"] == 1 and "drift_simulate" not in counts
    assert len(list((results(wd) / f"drift/shards/{NEW_DRIFT}").glob("*.parquet"))) == new_drift_session["n_new"]
    diff = new_drift_session["diff"]
    assert diff and all(f.startswith(f"{SMOKE}/drift/metrics/") for f in diff), diff
    assert "drift_30min_n" in diff[f"{SMOKE}/drift/metrics/loaded.json"], diff
    assert "up to date" in dvc(wd, "status").stdout.lower()


@pytest.mark.extended
def test_experiments_rerun_only_the_stages_of_the_changed_params(repo, new_session):
    wd = repo["wd"]
    # the tool report without one ablation: its stage re-runs, but no model trains again
    out = dvc_out(wd, "exp", "run", "-n", "mu-variants", "-S", "baseline.mu_max=0.35",
                  "-S", "tool_train.variants=[full]")
    assert ran_stages(out) == {"volume", "tool_models"}, out[-3000:]
    counts = job_counts(out)
    assert "papillarray_ingest" not in counts and "tool_ingest" not in counts and "tool_dataset" not in counts
    assert "tool_train" not in counts and counts["tool_model_report"] == 2, counts
    for scene in ("tool_normal", "tool_shear"):
        m = json.loads((results(wd) / f"{scene}/scores.json").read_text())
        assert "full" in m and "no_ref" not in m, scene
        orderings = (results(wd) / f"{scene}/tables/paper_orderings.md").read_text()   # none with one variant
        assert "none: no ordering is between two of full" in orderings and m["paper_orderings"] == [], scene
        assert sorted(p.name for p in (results(wd) / f"{scene}/metrics").iterdir()) == ["full.json"], scene
    params = json.loads(dvc(wd, "params", "diff", "--json").stdout)["params.yaml"]
    assert (params["baseline.mu_max"]["old"], params["baseline.mu_max"]["new"]) == (0.4, 0.35)
    variants = {k: yaml.safe_load(v) for k, v in params["tool_train.variants"].items()}   # DVC shows a list as text
    assert variants == {"old": ["full", "no_ref"], "new": ["full"]}, params
    show = dvc(wd, "exp", "show", "--md").stdout
    assert "mu-variants" in show and "baseline.mu_max" in show and "mu_star" in show, show[:2000]
    # only what differs: the changed parameters and the scores that moved, not every model's row
    changed = dvc(wd, "exp", "show", "--only-changed", "--md").stdout.splitlines()[0]
    assert "baseline.mu_max" in changed and "mu_star" in changed and "scale" not in changed, changed
    assert "fx_fy_fz.json:r2" not in changed, changed          # the MLPs did not re-run
    exp_diff = json.loads(dvc(wd, "exp", "diff", "HEAD", "mu-variants", "--json").stdout)
    assert exp_diff["params"]["params.yaml"]["baseline.mu_max"]["new"] == 0.35
    assert f"{SMOKE}/volume/metrics/baseline.json" in exp_diff["metrics"]
    # back to the committed state (the experiment stays in `dvc exp show`); Snakemake's records are
    # the experiment's until the restored results are marked current, once DVC has checked them
    git(wd, "checkout", "--", ".")
    dvc(wd, "checkout", "--force")
    assert "up to date" in dvc(wd, "status").stdout.lower()
    run([str(BIN / "python"), "workflow/scripts/mark_pulled.py"], wd)
    assert _planned_rules(wd) == set()


@pytest.mark.extended
def test_diff_tells_a_retrained_model_from_noise_and_fails_on_a_regression(repo, new_session):
    wd = repo["wd"]
    tp = [str(BIN / "tactilepipe"), "diff"]
    same = run(tp, wd)                                   # HEAD against the workspace: the committed build
    assert same.stdout.count(": unchanged") == 4, same.stdout
    # a training parameter: every model of the tool scenes trains again on the same splits
    dvc_out(wd, "exp", "run", "-n", "lr-up", "-S", "tool_train.lr=0.001")
    report = json.loads(run([*tp, "HEAD", "lr-up", "--json"], wd).stdout)
    assert report["volume"]["verdict"] == report["drift"]["verdict"] == "unchanged", report["volume"]
    scored = [r for scene in TOOL_SCENES for r in report[scene]["rows"] if r["how"].startswith("paired")]
    assert {r["model"] for r in scored} >= {"full", "no_ref"} and all(r["how"] == "paired over 2 draws" for r in scored)
    assert {r["verdict"] for r in scored} <= {"signal", "noise"}
    assert not any(r["model"].startswith("baseline") for r in scored)    # the baselines do not train
    md = run([*tp, "HEAD", "lr-up"], wd).stdout
    assert "| full | mae |" in md and "**tool_normal**:" in md
    # --fail-on: exit 1 past the worst worsening of a score, 0 short of it
    metric, worst = max(((r["metric"], r["worse_by"]) for r in scored), key=lambda mw: mw[1])
    assert worst > 0, scored
    failing = run([*tp, "HEAD", "lr-up", "--fail-on", f"{metric}={worst / 2}"], wd, check=False)
    assert failing.returncode == 1 and f"{metric} worse by" in failing.stderr, failing.stderr
    assert run([*tp, "HEAD", "lr-up", "--fail-on", f"{metric}={worst * 2}"], wd, check=False).returncode == 0
    git(wd, "checkout", "--", ".")
    dvc(wd, "checkout", "--force")
    run([str(BIN / "python"), "workflow/scripts/mark_pulled.py"], wd)
    assert _planned_rules(wd) == set()


def test_push_clone_pull_is_byte_identical_and_snakemake_has_nothing_to_do(repo, new_session, new_drift_session):
    wd, clone = repo["wd"], repo["root"] / "clone"
    dvc(wd, "push")
    assert any(repo["remote"].rglob("*"))
    run(["git", "clone", "-q", str(wd), str(clone)], repo["root"])
    assert not (clone / "raw/volume/sim-smoke").exists() and not (results(clone) / "volume/dataset.parquet").exists()
    assert (results(clone) / "volume/metrics/fy_fz.json").exists()       # metrics come with git
    # `make pull`: dvc pull, then, as DVC keeps no modification times and a clone has no Snakemake
    # records, the pulled results are marked up to date for Snakemake once DVC has found every
    # stage current by content
    mark = run([str(BIN / "python"), "workflow/scripts/mark_pulled.py", "--pull"], clone)
    assert "every stage up to date" in mark.stdout, mark.stdout + mark.stderr
    ours, theirs = tracked_files(wd), tracked_files(clone)
    assert sorted(theirs) == sorted(ours)
    assert [f for f in ours if ours[f] != theirs[f]] == []
    kinds = {Path(f).suffix for f in theirs}
    assert {".bag", ".csv", ".parquet", ".pt", ".json", ".png", ".md", ".npy"} <= kinds, kinds
    proc = snakemake(clone, "-n")
    assert "Nothing to be done" in proc.stdout + proc.stderr, proc.stdout[-3000:]
    assert "up to date" in dvc(clone, "status").stdout.lower()
    out = dvc_out(clone, "repro")
    assert ran_stages(out) == set(), out[-2000:]


def test_make_pull_with_nothing_to_pull_from_says_what_to_set_up_in_one_line(repo):
    """A fresh clone whose remote is missing, empty, holds other objects or is not set, or that has
    no dvc.lock: `make pull` stops with one line naming the remote and what to do (DVC's own output,
    thousands of lines for a missing remote, is kept in a log)."""
    wd, clone = repo["wd"], repo["root"] / "clone_no_remote"
    run(["git", "clone", "-q", str(wd), str(clone)], repo["root"])
    pull = [str(BIN / "python"), "workflow/scripts/mark_pulled.py", "--pull"]

    def one_line(*expected: str) -> str:
        proc = run(pull, clone, check=False)
        lines = proc.stderr.strip().splitlines()
        assert proc.returncode == 1 and len(lines) == 1, proc.stdout + proc.stderr
        assert all(e in lines[0] for e in expected), lines[0]
        return lines[0]

    elsewhere = repo["root"] / "no_such_remote"
    dvc(clone, "remote", "modify", "--local", "local", "url", str(elsewhere))
    one_line("'local'", str(elsewhere), "does not exist", "dvc push")
    elsewhere.mkdir()
    one_line("is empty")
    (elsewhere / "files/md5/00").mkdir(parents=True)
    (elsewhere / "files/md5/00/stray").write_text("not an object of this project")
    one_line("lacks", "of the objects dvc.lock names", ".dvc/tmp/pull.log")
    assert (clone / ".dvc/tmp/pull.log").read_text().strip()
    config = clone / ".dvc/config"
    config.write_text(config.read_text().replace("remote = local", ""))
    one_line("no default DVC remote", "dvc remote add -d")
    (clone / "dvc.lock").unlink()
    one_line("no dvc.lock", "make run")
    assert not (clone / "raw/volume/sim-smoke").exists()


def test_plots_show_offline_and_diff_between_commits(repo, new_session):
    wd = repo["wd"]
    # image plots (PNG paths) and data plots (a figure's CSV with its x, y and template)
    declared = [p for p in yaml.safe_load((wd / "dvc.yaml").read_text())["plots"] if isinstance(p, str)]
    dvc(wd, "plots", "show", "-o", "plots_show")
    html = (wd / "plots_show/index.html").read_text()
    for png in declared:
        assert Path(png).name in html or png.replace("/", "_") in html, png
    # the images are files beside the page; only the data plots' vega scripts come from a CDN
    remote = re.findall(r"(?:src|href)=\"(https?://[^\"]+)\"", html)
    assert all(re.search(r"/npm/vega(-lite|-embed)?@", u) for u in remote), remote
    dvc(wd, "plots", "diff", "HEAD~1", "HEAD", "-o", "plots_diff")
    diff_html = (wd / "plots_diff/index.html").read_text()
    assert "HEAD~1" in diff_html and "HEAD" in diff_html
    assert diff_html.count("<img") >= 2 * len(declared)
    images = sorted(p for p in (wd / "plots_diff").rglob("*.png"))
    assert len(images) >= 2 * len(declared)


@pytest.mark.extended
def test_marking_pulled_results_refuses_when_content_differs(repo, new_session):
    """A pulled clone whose code differs from what made the results: nothing is marked, and
    Snakemake still plans the rules that run the edited module."""
    wd, clone = repo["wd"], repo["root"] / "clone_edited"
    run(["git", "clone", "-q", str(wd), str(clone)], repo["root"])
    dvc(clone, "pull")
    with open(clone / "src/tactilepipe/drift/analyse.py", "a") as fh:
        fh.write("\n# an edit made after the results were pushed\n")
    mark = run([str(BIN / "python"), "workflow/scripts/mark_pulled.py"], clone, check=False)
    assert mark.returncode == 1 and "drift" in mark.stderr and "nothing is marked" in mark.stderr
    planned = job_counts(snakemake(clone, "-n").stdout)
    assert "drift_report" in planned


@pytest.mark.extended
def test_a_parameter_change_reruns_its_rules_without_snakemake_records(repo, new_session):
    """Where Snakemake has no record of earlier runs (a new machine, a deleted .snakemake/), a
    parameter change still re-runs exactly the rules that read it: the rules' parameter stamps
    are inputs, compared by file time."""
    wd, clone = repo["wd"], repo["root"] / "clone_params"
    run(["git", "clone", "-q", str(wd), str(clone)], repo["root"])
    dvc(clone, "pull")
    run([str(BIN / "python"), "workflow/scripts/mark_pulled.py"], clone)
    shutil.rmtree(clone / ".snakemake")
    assert _planned_rules(clone) == set()
    text = (clone / "params.yaml").read_text()
    assert text.count("  mu_max: 0.4") == 1
    (clone / "params.yaml").write_text(text.replace("  mu_max: 0.4", "  mu_max: 0.35"))
    assert _planned_rules(clone) == {"volume_baseline", "volume_report"}


# --- code-aware invalidation: each edit re-runs exactly the rules whose code it is in ---------------

# the drift scene analyses the real session taken in above, so its simulator is no job of the
# default target (its DVC stage still re-runs: it is one of dvc.yaml's stages)
VOLUME_ALL = {"volume_simulate", "papillarray_ingest", "volume_dataset", "volume_split",
              "volume_train", "volume_gridsearch", "volume_baseline", "volume_report", "drift_report"}
TOOL_DATA_ON = {"tool_ingest", "tool_clock_figure", "tool_dataset", "tool_split", "tool_data_report", "tool_train",
                "tool_model_report"}
EDITS = [   # (module, snakemake rules planned, DVC stages out of date, an output the edit must rewrite)
    ("volume/report.py", {"volume_report"}, {"volume"}, f"{SMOKE}/volume/scores.json"),
    ("drift/analyse.py", {"drift_report"}, {"drift"}, f"{SMOKE}/drift/fits.csv"),
    # planned only (None: no repro, which the cases above show; these would re-run what they did,
    # a simulator or whole scenes). A stage's CLI module is in its own code only: an edit of the
    # drift report's re-runs that report, not the drift simulator
    ("cli/drift_report.py", {"drift_report"}, {"drift"}, None),
    ("tool/model/network.py", {"tool_train", "tool_model_report"}, {"tool_models"}, None),
    ("tool/data/ingest.py", TOOL_DATA_ON, {"tool_data", "tool_models"}, None),
    # the drift simulator shares the pillar physics (papillarray/physics.py), not the lift simulator
    ("volume/simulate.py", VOLUME_ALL - {"drift_report"}, {"volume_simulate", "volume"}, None),
    ("papillarray/messages.py", VOLUME_ALL, {"volume_simulate", "drift_simulate", "volume", "drift"}, None),
]


def _planned_rules(wd: Path) -> set[str]:
    # with the profile a plain `snakemake` finds in a checkout (through the `profiles` link), as DVC's
    # stages and mark_pulled.py run it: it compares checksums of inputs up to 2 GB, not only times
    out = snakemake(wd, "-n", "--workflow-profile", "workflow/profiles/default").stdout
    return set(job_counts(out)) - {"all"}


def _stale_stages(wd: Path) -> set[str]:
    return set(json.loads(dvc(wd, "status", "--json").stdout or "{}"))


@pytest.mark.parametrize("module, rules, stages, rewritten", EDITS, ids=[e[0] for e in EDITS])
def test_editing_a_module_reruns_exactly_the_rules_that_run_it(repo, new_session, new_drift_session, module, rules, stages,
                                                              rewritten):
    # starts clean: every test before this one leaves the project up to date, and asserts it
    wd = repo["wd"]
    path = wd / "src/tactilepipe" / module
    original, before_edit = path.read_text(), path.stat()
    if module == "volume/report.py":          # a real change: one more key in scores.json
        assert original.count('        "scale": p["scale"],') == 1
        path.write_text(original.replace('        "scale": p["scale"],', '        "scale": p["scale"],\n        "edited": 1,'))
    else:                                     # a comment counts too (conservative, never stale)
        path.write_text(original + "\n# edited\n")
    try:
        assert _planned_rules(wd) == rules
        assert _stale_stages(wd) == stages
    finally:
        if rewritten is None:                 # planned only: the file exactly as it was, time included
            path.write_text(original)
            os.utime(path, ns=(before_edit.st_atime_ns, before_edit.st_mtime_ns))
    if rewritten is None:
        return
    before = (wd / rewritten).stat().st_mtime_ns
    out = dvc_out(wd, "repro")
    assert ran_stages(out) == stages, out[-2000:]
    assert (wd / rewritten).stat().st_mtime_ns > before, rewritten
    if module == "volume/report.py":
        assert json.loads((wd / rewritten).read_text())["edited"] == 1
    assert ran_stages(dvc_out(wd, "repro")) == set()
    assert _planned_rules(wd) == set()


def test_a_module_rewritten_with_the_same_text_reruns_nothing(repo, new_session):
    """A newer file with unchanged content (an editor's save, a checkout) re-runs nothing: Snakemake
    compares the input's checksum once its time is newer, and DVC compares content."""
    wd = repo["wd"]
    path = wd / "src/tactilepipe/tool/model/network.py"
    path.write_text(path.read_text())
    assert path.stat().st_mtime_ns > (results(wd) / "tool_normal/metrics/full.json").stat().st_mtime_ns
    assert _planned_rules(wd) == set() and _stale_stages(wd) == set()
