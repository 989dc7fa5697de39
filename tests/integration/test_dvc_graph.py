"""dvc.yaml and the Snakemake graph must agree: every file a rule writes is an out of exactly one
stage, every file a stage's jobs read from elsewhere (raw recordings, other stages' outputs) is a
dep of that stage, and each stage's command builds only its own and upstream stages' files.

The Snakemake side comes from dry runs (`snakemake -n`, which prints every job's input and output
files) of each stage's own command, in an empty copy of the project at the smoke scale."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest
import yaml

from support.dvc_graph import covers, dvc_stages
from support.project import BIN, REPO, SMOKE, copy_project, run

pytestmark = pytest.mark.integration

# Files a stage declares that no Snakemake rule lists as an output, each with the reason it is
# accepted. Keep this empty: every entry is a file Snakemake cannot rebuild if it goes missing.
KNOWN_UNDECLARED_OUTS: dict[str, str] = {}


_DRY_RUNS: dict[tuple, list[dict]] = {}


def dry_run_jobs(wd: Path, args: list[str]) -> list[dict]:
    """Jobs of `snakemake -n <args>` as [{rule, input: [...], output: [...]}] (cached: the graph
    does not depend on dvc.yaml)."""
    key = (str(wd), *args)
    if key not in _DRY_RUNS:
        _DRY_RUNS[key] = _parse_jobs(run([str(BIN / "snakemake"), "-n", *args], wd).stdout)
    return _DRY_RUNS[key]


def _parse_jobs(out: str) -> list[dict]:
    jobs, job = [], None
    for line in out.splitlines():
        m = re.match(r"^(?:local)?rule (\w+):$", line)
        if m:
            job = {"rule": m.group(1), "input": [], "output": []}
            jobs.append(job)
        elif job is not None and (m := re.match(r"^    (input|output): (.*)$", line)):
            job[m.group(1)] = [f for f in m.group(2).split(", ") if f]
    return jobs


def stage_targets(cmd: str) -> list[str]:
    argv = shlex.split(cmd)
    assert Path(argv[0]).name == "snakemake", cmd
    return argv[1:]


def check_agreement(wd: Path, dvc_yaml: Path) -> list[str]:
    """Every disagreement between dvc.yaml and the Snakemake graph, one line each."""
    params = yaml.safe_load((wd / "params.yaml").read_text())
    stages = dvc_stages(dvc_yaml, params)
    problems = []

    # upstream stages in DVC's graph: a dep overlapping another stage's out
    def overlaps(a: str, b: str) -> bool:
        return covers(a, b) or covers(b, a)
    direct = {s: {t for t in stages if t != s and any(overlaps(d, o) for d in stages[s]["deps"]
                                                      for o in stages[t]["outs"])} for s in stages}
    upstream = {}
    for s in stages:
        seen, todo = set(), list(direct[s])
        while todo:
            t = todo.pop()
            if t not in seen:
                seen.add(t)
                todo.extend(direct[t])
        upstream[s] = seen

    def owner(path: str) -> list[str]:
        return [s for s in stages if any(covers(path, o) for o in stages[s]["outs"])]

    producer: dict[str, str] = {}         # Snakemake output -> the stage that declares it
    per_stage_jobs = {}
    for s, st in stages.items():
        jobs = dry_run_jobs(wd, stage_targets(st["cmd"]))
        per_stage_jobs[s] = jobs
        for job in jobs:
            for f in job["output"]:
                owners = owner(f)
                if not owners:
                    problems.append(f"rule {job['rule']} writes {f}: no stage declares it as an out")
                elif len(owners) > 1:
                    problems.append(f"{f} is an out of several stages: {owners}")
                else:
                    producer[f] = owners[0]
                    if owners[0] != s and owners[0] not in upstream[s]:
                        problems.append(f"stage {s}'s command runs rule {job['rule']} for {f}, an out of "
                                        f"stage {owners[0]} which {s} does not depend on")
    full = dry_run_jobs(wd, [])                   # what plain `snakemake --cores 2` builds
    for job in full:
        for f in job["output"]:
            if not owner(f):
                problems.append(f"rule {job['rule']} writes {f} (default target): no stage declares it")
    for s, jobs in per_stage_jobs.items():
        own = [j for j in jobs if j["output"] and all(producer.get(f) == s for f in j["output"])]
        if not own:
            problems.append(f"stage {s}: its command runs no rule whose outputs it declares")
        for job in own:
            for f in job["input"]:
                if producer.get(f) == s:
                    continue                      # made inside the same stage
                if f.startswith(f"{SMOKE}/params/") or "/changed-params/" in f:
                    continue                      # parameter stamps (a dry run's changed ones in a scratch
                                                  # folder): DVC tracks the values as params
                if f.startswith(".tactilepipe/content/") or "/changed-content/" in f:
                    continue                      # content stamps: local state; DVC hashes raw/ itself
                if not any(covers(f, d) for d in stages[s]["deps"]):
                    origin = f"stage {producer[f]}" if f in producer else "outside the graph"
                    problems.append(f"stage {s}: rule {job['rule']} reads {f} ({origin}) but no dep covers it")
    for s, st in stages.items():
        for o in st["outs"]:
            if o in KNOWN_UNDECLARED_OUTS:
                continue
            if not any(covers(f, o) for f in producer):
                problems.append(f"stage {s} declares out {o} that no rule writes")
    return problems


@pytest.fixture(scope="module")
def smoke_copy(tmp_path_factory) -> Path:
    return copy_project(tmp_path_factory.mktemp("graph"), scale="smoke")


def test_dvc_yaml_and_snakemake_graph_agree(smoke_copy: Path):
    problems = check_agreement(smoke_copy, smoke_copy / "dvc.yaml")
    assert problems == [], "\n".join(problems)


def _mutate(wd: Path, stage: str, key: str, remove: str) -> Path:
    doc = yaml.safe_load((wd / "dvc.yaml").read_text())
    items = doc["stages"][stage][key]
    kept = [i for i in items if (next(iter(i)) if isinstance(i, dict) else i) != remove]
    assert len(kept) == len(items) - 1, (stage, key, remove)
    doc["stages"][stage][key] = kept
    path = wd / f"dvc.mutated.{stage}.{key}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def test_a_missing_dep_is_caught(smoke_copy: Path):
    problems = check_agreement(smoke_copy, _mutate(smoke_copy, "drift", "deps", "raw/drift"))
    assert any("stage drift: rule papillarray_ingest reads raw/drift/sim-smoke/" in p and "drift_simulate" in p
               for p in problems), problems


def test_an_undeclared_output_is_caught(smoke_copy: Path):
    # dvc.yaml names the build's folder as DVC interpolates it (results/${scale}: the smoke build here)
    problems = check_agreement(smoke_copy, _mutate(smoke_copy, "volume", "outs", "results/${scale}/volume/folds.json"))
    assert f"rule volume_split writes {SMOKE}/volume/folds.json: no stage declares it as an out" in problems, problems
    problems = check_agreement(smoke_copy, _mutate(smoke_copy, "tool_models", "deps", "results/${scale}/tool_shear/splits"))
    assert any(p.startswith(f"stage tool_models: rule tool_train reads {SMOKE}/tool_shear/splits/") for p in problems), \
        problems


def test_committed_dvc_yaml_is_what_the_generator_makes():
    """dvc.yaml is generated from the Snakemake graph; a stale committed copy fails here."""
    proc = run([str(BIN / "python"), "workflow/scripts/dvc_yaml.py", "--check"], REPO, check=False)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]


def test_generator_lists_each_stage_code_closure_and_declared_params():
    stages = yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"]
    from tactilepipe.pipeline import codedeps
    drift_code = {d for d in stages["drift_simulate"]["deps"] if d.endswith(".py")}
    # the drift simulator shares the pillar physics with the lift simulator, not the lift simulator
    assert {"src/tactilepipe/papillarray/physics.py", "src/tactilepipe/papillarray/viscoelastic.py"} <= drift_code
    assert "src/tactilepipe/volume/simulate.py" not in drift_code
    # a stage's CLI code is its own module: no other stage's
    assert "src/tactilepipe/cli/drift_simulate.py" in drift_code
    assert not drift_code & {"src/tactilepipe/cli/volume_simulate.py", "src/tactilepipe/cli/tool_simulate.py"}
    assert "src/tactilepipe/cli/drift_report.py" not in stages["volume"]["deps"]
    # its code, and the workflow's own library (the session sheet, scenes, stamps: as common.smk)
    # with the studies' contracts it reads (each study's sessions, scenes and outputs)
    own = lambda d: d.startswith("src/tactilepipe/pipeline/") or d.endswith("/contract.py") or \
        d in ("src/tactilepipe/studies.py", "src/tactilepipe/core/study.py")
    library = set.intersection(*({d for d in s["deps"] if own(d)} for s in stages.values()))
    assert {"src/tactilepipe/pipeline/sessions.py", "src/tactilepipe/pipeline/stamp_keeper.py",
            "src/tactilepipe/studies.py", "src/tactilepipe/tool/contract.py"} <= library
    assert drift_code == set(codedeps.stage_files("drift-simulate")) | library
    assert "src/tactilepipe/tool/model/network.py" in stages["tool_models"]["deps"]
    # every rule runs `python -m tactilepipe`: the package's __main__ is code of every stage
    assert all("src/tactilepipe/__main__.py" in s["deps"] for s in stages.values())
    assert "src/tactilepipe/tool/model/network.py" not in stages["volume"]["deps"]
    # the analysis reads no simulator setting (provenance.json records them for a simulated session)
    assert not any(k.startswith("simulate") for k in codedeps.stage_param_keys("drift-report"))
    assert "src/tactilepipe/drift/simulate.py" in stages["drift"]["deps"]   # the simulated session's provenance
    assert {"workflow/rules/drift.smk", "workflow/rules/ingest.smk", "workflow/rules/common.smk"} <= set(stages["drift"]["deps"])
    # the training stage declares the whole tool_train group (its typed settings and the run-shaping
    # keys): DVC lists the group once, none of its keys again
    models = stages["tool_models"]["params"]
    assert "tool_train" in models and not any(k.startswith("tool_train.") for k in models), models
    assert "tool_train" not in stages["tool_data"]["params"]
    for stage in stages.values():
        assert stage["params"][-1] == "scales.${scale}" and "scale" in stage["params"]
