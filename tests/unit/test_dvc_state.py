"""Which dvc.yaml stages a finished Snakemake run records for DVC, and when it records none
(pipeline/dvc_state.py; end to end with real Snakemake and DVC: tests/integration/test_dvc_workflow.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tactilepipe.core.errors import TactilepipeError
from tactilepipe.pipeline import dvc_state

DVC_YAML = """stages:
  volume_simulate:
    cmd: snakemake --cores 2 --workflow-profile workflow/profiles/default raw/volume/sim-${scale}/lifts.csv
  volume:
    cmd: snakemake --cores 2 --workflow-profile workflow/profiles/default volume
  tool_models:
    cmd: snakemake --cores 2 --workflow-profile workflow/profiles/default tool_normal tool_shear
  unpack:
    cmd: tactilepipe study000-unpack raw/downloads/data.zip
"""
RULE_INPUTS = {"volume": ["results/smoke/volume/metrics/fy.json", "results/smoke/volume/tables/t1.md"],
               "tool_normal": ["results/smoke/tool_normal/metrics/full.json"],
               "tool_shear": ["results/smoke/tool_shear/metrics/full.json"]}


def files_of(target: str) -> list[str]:
    return RULE_INPUTS.get(target, [target])


@pytest.fixture
def project(tmp_path: Path) -> Path:
    (tmp_path / "dvc.yaml").write_text(DVC_YAML)
    (tmp_path / ".dvc").mkdir()
    return tmp_path


def test_each_stage_targets_are_read_from_its_command_at_the_scale(project):
    targets = dvc_state.stage_targets(project, "smoke")
    assert targets == {"volume_simulate": ["raw/volume/sim-smoke/lifts.csv"], "volume": ["volume"],
                       "tool_models": ["tool_normal", "tool_shear"]}   # a non-Snakemake stage is not ours


def test_a_stage_is_recorded_only_when_the_run_made_every_file_of_every_target(project):
    targets = dvc_state.stage_targets(project, "smoke")
    made = {"raw/volume/sim-smoke/lifts.csv", *RULE_INPUTS["volume"], *RULE_INPUTS["tool_normal"]}
    # tool_shear was not part of this run: tool_models stays as DVC last saw it
    assert dvc_state.stages_made(targets, made, files_of) == ["volume_simulate", "volume"]
    made.discard("results/smoke/volume/tables/t1.md")
    assert dvc_state.stages_made(targets, made, files_of) == ["volume_simulate"]


def test_nothing_is_recorded_inside_dvc_repro_outside_a_dvc_project_or_with_overrides(project, tmp_path_factory):
    assert dvc_state.why_not_recorded(project, {}, {}) is None
    assert dvc_state.why_not_recorded(project, {}, {"DVC_STAGE": "volume"}) == ""       # DVC writes the lock
    bare = tmp_path_factory.mktemp("bare")
    (bare / "dvc.yaml").write_text(DVC_YAML)
    assert dvc_state.why_not_recorded(bare, {}, {}) == ""                                 # no .dvc/
    said = dvc_state.why_not_recorded(project, {"scale": "smoke", "build": "alt"}, {})
    assert said.startswith("DVC: not recorded") and "build, scale" in said


def test_a_failed_commit_is_one_line_naming_the_stages(project, tmp_path):
    fake = tmp_path / "dvc"
    fake.write_text("#!/bin/sh\necho 'ERROR: output results/smoke/volume does not exist' >&2\nexit 1\n")
    fake.chmod(0o755)
    with pytest.raises(TactilepipeError) as err:
        dvc_state.record(project, ["volume"], str(fake))
    message = str(err.value)
    assert "dvc commit volume" in message and "does not exist" in message and "\n" not in message
    assert "nothing recorded" in dvc_state.record(project, [], str(fake))


def test_a_run_with_nothing_to_do_records_only_stages_whose_lock_is_behind(project):
    import os
    stages = ["volume_simulate", "volume", "tool_models"]
    assert dvc_state.stale_stages(project, stages) == stages                 # no dvc.lock yet
    text = DVC_YAML.replace("    cmd: snakemake --cores 2 --workflow-profile workflow/profiles/default volume\n",
                            "    cmd: snakemake --cores 2 --workflow-profile workflow/profiles/default volume\n"
                            "    deps:\n    - workflow/rules/volume.smk\n    - raw/volume\n")
    (project / "dvc.yaml").write_text(text)
    (project / "params.yaml").write_text("scale: smoke\n")
    (project / "workflow/rules").mkdir(parents=True)
    (project / "workflow/rules/volume.smk").write_text("rule volume_dataset: ...\n")
    (project / "raw/volume").mkdir(parents=True)
    (project / "dvc.lock").write_text("stages:\n  volume: {}\n  tool_models: {}\n")
    old, lock_time = 1_000_000_000_000_000_000, 2_000_000_000_000_000_000
    for path in ("dvc.yaml", "params.yaml", "workflow/rules/volume.smk", "raw/volume"):
        os.utime(project / path, ns=(old, old))
    os.utime(project / "dvc.lock", ns=(lock_time, lock_time))
    # volume_simulate is not in the lock; the others are current
    assert dvc_state.stale_stages(project, stages) == ["volume_simulate"]
    # a rule file's comment edited: Snakemake has nothing to do, DVC's record of that stage is behind
    os.utime(project / "workflow/rules/volume.smk", ns=(lock_time + 1, lock_time + 1))
    assert dvc_state.stale_stages(project, stages) == ["volume_simulate", "volume"]
    os.utime(project / "workflow/rules/volume.smk", ns=(old, old))
    os.utime(project / "raw/volume", ns=(lock_time + 1, lock_time + 1))      # a folder is data: not looked at
    assert dvc_state.stale_stages(project, stages) == ["volume_simulate"]
    os.utime(project / "params.yaml", ns=(lock_time + 1, lock_time + 1))     # every stage reads params.yaml
    assert dvc_state.stale_stages(project, stages) == stages
