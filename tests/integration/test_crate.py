"""`tactilepipe provenance --crate`: a real Snakemake build's provenance as a Workflow Run RO-Crate,
loaded back with ro-crate-py; its sessions named by the hash `dvc add` records for them."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from datetime import datetime
from importlib import metadata

import pytest
import yaml

from support.project import SMOKE, copy_project, git, results, run, snakemake

pytestmark = [pytest.mark.integration, pytest.mark.slow]

PROFILES = {"https://w3id.org/ro/wfrun/process/0.5", "https://w3id.org/ro/wfrun/workflow/0.5",
            "https://w3id.org/workflowhub/workflow-ro-crate/1.0"}
AGENT = "https://orcid.org/0000-0002-1825-0097"
SESSION = "raw/drift/sim-smoke"


@pytest.fixture(scope="module")
def build(tmp_path_factory):
    """The drift scene built at the smoke scale by real Snakemake in a committed project copy,
    with the clock read before and after."""
    wd = copy_project(tmp_path_factory.mktemp("crate"), scale="smoke")
    git(wd, "init", "-q")
    git(wd, "add", "-A")
    git(wd, "-c", "user.name=t", "-c", "user.email=t@t", "-c", "commit.gpgsign=false", "commit", "-q", "-m", "code")
    before = time.time()
    snakemake(wd, "--config", "scenes=[drift]")
    yield wd, before, time.time()
    shutil.rmtree(wd, ignore_errors=True)


def _crate(wd, out, *extra):
    return run([sys.executable, "-m", "tactilepipe", "provenance", "--crate", str(out), "--build", "smoke", *extra], wd)


def _dvc_add_md5(folder, tmp_path):
    """What `dvc add` records for a copy of ``folder`` in a fresh DVC project, and its cache."""
    repo = tmp_path / "dvcrepo"
    subprocess.run(["git", "init", "-q", str(repo)], check=True)
    run([sys.executable, "-m", "dvc", "init", "-q"], repo)
    shutil.copytree(folder, repo / "session")
    run([sys.executable, "-m", "dvc", "add", "-q", "session"], repo)
    md5 = yaml.safe_load((repo / "session.dvc").read_text())["outs"][0]["md5"]
    return md5, repo / ".dvc" / "cache"


def _ids(value) -> list[str]:
    return [v.id if hasattr(v, "id") else v["@id"] for v in (value if isinstance(value, list) else [value])]


def test_the_crate_loads_back_as_a_workflow_run_of_the_build(build, tmp_path):
    from rocrate.rocrate import ROCrate
    wd, before, after = build
    out = tmp_path / "crate"
    printed = _crate(wd, out, "--agent", AGENT).stdout
    assert "2 runs (2 with Snakemake's start and end times)" in printed, printed
    crate = ROCrate(out)

    # the profiles, each a CreativeWork of the crate
    assert PROFILES <= set(_ids(crate.root_dataset["conformsTo"]))
    assert all(crate.get(p).type == "CreativeWork" for p in PROFILES)
    # the main workflow: the Snakefile in Snakemake's language, at the commit the build ran
    workflow = crate.mainEntity
    assert workflow.id == "Snakefile" and "ComputationalWorkflow" in workflow.type
    assert (out / "Snakefile").read_bytes() == (wd / "Snakefile").read_bytes()
    assert workflow["programmingLanguage"]["version"] == metadata.version("snakemake")
    commit = run(["git", "rev-parse", "HEAD"], wd).stdout.strip()
    assert workflow["version"] == commit
    software = {e["name"]: e["softwareVersion"] for e in workflow["softwareRequirements"]}
    assert software["snakemake"] == metadata.version("snakemake") and software["dvc"] == metadata.version("dvc")
    assert software["numpy"] == metadata.version("numpy") and software["python"] == sys.version.split()[0]

    # one run of the workflow for the build and one for its scene, both mentioned by the root
    actions = {a.id: a for a in crate.get_entities() if a.type == "CreateAction"}
    assert set(actions) == {"#build-smoke", "#scene-drift"}
    assert set(_ids(crate.root_dataset["mentions"])) == set(actions)
    for action in actions.values():
        assert action["instrument"].id == workflow.id
        assert action["agent"].id == AGENT
        # Snakemake's own record of its jobs: within the build's wall clock, in order
        start, end = (datetime.fromisoformat(action[k]).timestamp() for k in ("startTime", "endTime"))
        assert before <= start < end <= after, (before, start, end, after)
        machine = action["location"][0] if isinstance(action["location"], list) else action["location"]
        cpu = {p["name"]: p["value"] for p in machine["additionalProperty"]}
        assert cpu["machine"] and cpu["python"] == sys.version.split()[0]
        # the outputs: files of the crate, byte for byte the build's, each with its DVC md5
        results_ = action["result"]
        assert f"{SMOKE}/drift/metrics/loaded.json" in _ids(results_)
        for f in results_:
            assert (out / f.id).read_bytes() == (wd / f.id).read_bytes(), f.id
            assert len(f["identifier"]["value"]) == 32
    build_run, scene_run = actions["#build-smoke"], actions["#scene-drift"]
    # the only scene: its report is the build's last job, its simulation the first
    assert (scene_run["startTime"], scene_run["endTime"]) == (build_run["startTime"], build_run["endTime"])

    # the input: the session, by the hash `dvc add` records for it (and provenance.json too)
    session = next(o for o in scene_run["object"] if o.get("alternateName") == SESSION)
    assert session.type == "Dataset"
    md5, cache = _dvc_add_md5(wd / SESSION, tmp_path)
    assert session["identifier"]["value"] == md5 and md5.endswith(".dir")
    # and names the object DVC stores it as: the path the crate gives, in the cache `dvc add` filled
    where = session["identifier"]["description"].split("the object ", 1)[1].split()[0]
    assert (cache / where).is_file(), where
    assert json.loads((results(wd) / "drift/provenance.json").read_text())["sessions"][SESSION] == md5
    # the parameters: each value the stage was given, as its stamp records it
    stamp = json.loads((results(wd) / "params/drift-report.json").read_text())
    given = {o["name"]: o["value"] for o in scene_run["object"] if o.type == "PropertyValue"}
    assert given["drift-report: drift.tolerance_n"] == stamp["values"]["drift"]["tolerance_n"]
    assert json.loads(given["drift-report: drift.poly_degrees"]) == stamp["values"]["drift"]["poly_degrees"]
    assert session.id in _ids(build_run["object"])
    assert f"{SMOKE}/params/drift-report.json" in _ids(build_run["object"])


def test_a_build_without_provenance_is_named(build, tmp_path):
    wd, _, _ = build
    proc = run([sys.executable, "-m", "tactilepipe", "provenance", "--crate", str(tmp_path / "c"), "--build", "none"],
               wd, check=False)
    assert proc.returncode == 2
    assert "results/none: no scene has a provenance.json: build it first" in proc.stderr
    assert "Traceback" not in proc.stderr
