"""A stage's code (pipeline/codedeps.py) is what its function runs, and each study's parameter
checks are code of that study's stages only: editing one study's check re-runs no other study."""

from __future__ import annotations

import ast
import json
import os
import shutil
import subprocess
import sys

import pytest

from tactilepipe.cli import main as cli
from tactilepipe.cli.registry import command
from tactilepipe.core.errors import ConfigError, TactilepipeError
from tactilepipe import studies
from tactilepipe.pipeline import codedeps

from support.project import REPO

# the stages by the CLI module that declares them
HOMES = {stage: module for stage, (module, _) in codedeps._declared_stages().items()}
TOOL_HOMES = {m for m in HOMES.values() if m.startswith("tactilepipe.cli.tool_")} | \
    {f"tactilepipe.cli.{m}" for m in ("study000_unpack", "tool_evaluate", "study000_table", "rig", "predict", "realism",
                                   "portability")}
PAPILLARRAY_HOMES = {m for m in HOMES.values() if m.startswith("tactilepipe.cli.volume_")} | \
    {"tactilepipe.cli.papillarray_ingest", "tactilepipe.cli.drift_simulate", "tactilepipe.cli.drift_report"}
TOOL_STAGES = sorted(s for s, m in HOMES.items() if m in TOOL_HOMES)
PAPILLARRAY_STAGES = sorted(s for s, m in HOMES.items() if m in PAPILLARRAY_HOMES)
DRIFT_STAGES = sorted(s for s, m in HOMES.items() if m.startswith("tactilepipe.cli.drift_"))

# one message of each study's checks, and the file that must hold it: a stage whose code holds
# the text runs that check's code (on main, core/config.py held all three and was every stage's)
VOLUME_CHECK = ("src/tactilepipe/volume/checks.py", "baseline.mu_min must be below baseline.mu_max")
AXES_CHECK = ("src/tactilepipe/papillarray/checks.py", "must take each recorded axis x, y, z once")
TOOL_CHECK = ("src/tactilepipe/tool/checks.py", "tool_split.fractions must sum to 1")


def _code(stage: str) -> str:
    return "\n".join((REPO / f).read_text() for f in codedeps.stage_files(stage))


def _under(stage: str, *packages: str) -> list[str]:
    return sorted(m for m in codedeps.stage_modules(stage)
                  if any(m == f"tactilepipe.{p}" or m.startswith(f"tactilepipe.{p}.") for p in packages))


def test_the_stage_lists_cover_every_study():
    assert {"tool-train", "tool-split", "study000-unpack", "live"} <= set(TOOL_STAGES)
    assert {"volume-simulate", "volume-split", "papillarray-ingest", "drift-simulate", "drift-report"} <= \
        set(PAPILLARRAY_STAGES)
    for path, message in (VOLUME_CHECK, AXES_CHECK, TOOL_CHECK):
        assert message in (REPO / path).read_text()


def test_each_tool_volume_and_drift_stage_is_its_own_module_and_runs_no_other_stages_module():
    # editing one stage's declaration or function re-runs that stage's jobs only
    own = {m for m in HOMES.values() if m.startswith(("tactilepipe.cli.tool_", "tactilepipe.cli.volume_",
                                                       "tactilepipe.cli.drift_"))}
    assert len(own) == len([s for s, m in HOMES.items() if m in own]) >= 18
    for stage, module in HOMES.items():
        if module in own:
            assert codedeps.stage_modules(stage) & set(HOMES.values()) == {module}, stage


def test_a_tool_stage_holds_no_volume_drift_or_papillarray_code_nor_their_checks():
    for stage in TOOL_STAGES:
        assert _under(stage, "volume", "drift", "papillarray") == [], stage
        code = _code(stage)
        assert VOLUME_CHECK[1] not in code and AXES_CHECK[1] not in code, stage
        assert "tactilepipe.studies" not in codedeps.stage_modules(stage), stage


def test_a_volume_or_drift_stage_holds_no_tool_code_nor_its_checks():
    for stage in PAPILLARRAY_STAGES:
        assert _under(stage, "tool") == [], stage
        assert TOOL_CHECK[1] not in _code(stage), stage
        assert "tactilepipe.studies" not in codedeps.stage_modules(stage), stage
    for stage in DRIFT_STAGES:                           # the sensor's check, not the lifts'
        assert "tactilepipe.volume.checks" not in codedeps.stage_modules(stage), stage
        assert AXES_CHECK[1] in _code(stage) and VOLUME_CHECK[1] not in _code(stage), stage


def test_each_stage_holds_its_own_studys_checks():
    for stage in TOOL_STAGES:
        if codedeps.stage_param_keys(stage):
            assert "tactilepipe.tool.checks" in codedeps.stage_modules(stage), stage
    for stage in PAPILLARRAY_STAGES:
        assert "tactilepipe.papillarray.checks" in codedeps.stage_modules(stage), stage
    assert "tactilepipe.volume.checks" in codedeps.stage_modules("volume-split")


def test_a_module_level_import_counts_only_where_the_stage_uses_it():
    # tool-split's declaration names no --scene: the scene names are not its code
    assert "tactilepipe.tool.scenes" not in codedeps.stage_modules("tool-split")
    assert "tactilepipe.tool.scenes" in codedeps.stage_modules("tool-model-report")   # SCENE's choices
    # what cli/main.py runs for every stage (stage_params) counts, imported by its module or not
    for stage in ("study000-unpack", "volume-split", "live"):
        assert {"tactilepipe.cli.common", "tactilepipe.core.config"} <= codedeps.stage_modules(stage), stage
    tree = ast.parse("from tactilepipe.tool.scenes import TOOL_SCENES\n"
                     "from tactilepipe.volume import checks as volume_checks\n"
                     "from tactilepipe.core.atomic import *\n"
                     "import tactilepipe.drift.analyse\n"
                     "import tactilepipe.drift.figures as unused\n"
                     "try:\n    from tactilepipe.core.tables import x\nexcept ImportError:\n    pass\n")
    found = codedeps._module_level_imports(tree, "tactilepipe.cli.x", {"volume_checks"})
    assert found == {"tactilepipe.volume", "tactilepipe.volume.checks", "tactilepipe.core.atomic",
                     "tactilepipe.drift.analyse", "tactilepipe.core.tables"}


def _fingerprints(src, env) -> dict:
    script = ("import json; from tactilepipe.pipeline import codedeps as c; "
              "print(json.dumps({s: c.stage_fingerprint(s) for s in sorted(c._declared_stages())}))")
    out = subprocess.run([sys.executable, "-c", script], env={**env, "PYTHONPATH": str(src)},
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def test_editing_one_studys_checks_changes_no_other_studys_fingerprint(tmp_path):
    src = tmp_path / "src"
    shutil.copytree(REPO / "src" / "tactilepipe", src / "tactilepipe", ignore=shutil.ignore_patterns("__pycache__"))
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache")}
    before = _fingerprints(src, env)
    for path in ("volume/checks.py", "tool/checks.py"):
        with open(src / "tactilepipe" / path, "a") as fh:
            fh.write("# edited\n")
    after = _fingerprints(src, env)
    changed = {s for s in before if before[s] != after[s]}
    # both files were edited: a stage holding either changed, a stage holding neither did not
    assert changed >= {"volume-split", "volume-simulate", "tool-train", "tool-simulate"}
    assert not changed & set(DRIFT_STAGES) and "papillarray-ingest" not in changed
    with open(src / "tactilepipe" / "tool/checks.py", "a") as fh:
        fh.write("# edited again\n")
    again = _fingerprints(src, env)
    changed = {s for s in after if after[s] != again[s]}
    # diff, sessions and provenance (which finds the build params.yaml names) check the whole file,
    # as the workflow does: they hold every study's checks
    assert changed and changed <= set(TOOL_STAGES) | {"diff", "sessions", "provenance"}, changed
    assert not changed & set(PAPILLARRAY_STAGES)


# --- the moved checks still refuse their bad inputs --------------------------------------------------

BAD = {
    "volume": ({"baseline": {"mu_min": 0.4, "mu_max": 0.1}}, VOLUME_CHECK[1]),
    "axes": ({"papillarray_axes": {"sensor_1": {"x": "+x", "y": "+x", "z": "+z"}}}, AXES_CHECK[1]),
    "tool": ({"tool_split": {"fractions": [0.5, 0.2, 0.2]}}, TOOL_CHECK[1]),
}


def _by_hand(capsys, stage_args, override) -> str:
    code = cli.main([*stage_args, "--params", str(REPO / "params.yaml"), "--override", json.dumps(override)])
    err = capsys.readouterr().err
    assert code != 0, err
    return err


@pytest.mark.parametrize("stage_args, bad", [
    (["volume-split", "--dataset", "absent.parquet", "--out", "folds.json"], "volume"),
    (["volume-split", "--dataset", "absent.parquet", "--out", "folds.json"], "axes"),
    (["drift-report", "--in-dir", "d", "--shards", "a.parquet", "--session-meta", "session.json"], "axes"),
    (["tool-split", "--data-dir", "absent", "--split", "frame", "--label", "normal", "--out", "s.json"], "tool"),
], ids=["volume-split/volume", "volume-split/axes", "drift-report/axes", "tool-split/tool"])
def test_a_stage_by_hand_refuses_what_its_studys_checks_refuse(capsys, tmp_path, monkeypatch, stage_args, bad):
    monkeypatch.chdir(tmp_path)
    override, message = BAD[bad]
    err = _by_hand(capsys, stage_args, override)
    assert message in err and err.count("\n") == 1, err


def test_a_stage_by_hand_runs_only_its_own_studys_checks(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    tool_split = ["tool-split", "--data-dir", "absent", "--split", "frame", "--label", "normal", "--out", "s.json"]
    err = _by_hand(capsys, tool_split, BAD["volume"][0])          # past the checks, to the missing data set
    assert VOLUME_CHECK[1] not in err and "absent" in err, err
    err = _by_hand(capsys, ["volume-split", "--dataset", "absent.parquet", "--out", "f.json"], BAD["tool"][0])
    assert TOOL_CHECK[1] not in err and "absent.parquet" in err, err


@pytest.mark.parametrize("bad", sorted(BAD))
def test_the_full_validation_runs_every_studys_checks(bad):
    import yaml
    from tactilepipe.core.config import deep_merge, resolve
    override, message = BAD[bad]
    raw = deep_merge(yaml.safe_load((REPO / "params.yaml").read_text()), override)
    resolve(raw, "params.yaml", override)                        # the schema alone lets it through
    with pytest.raises(ConfigError, match=message):
        studies.resolve(raw, "params.yaml", override)
    with pytest.raises(ConfigError, match=message):
        studies.load_params(REPO / "params.yaml", override)


def test_the_full_validation_holds_every_studys_checks_and_the_workflow_runs_it():
    # a study's checks module, wherever it is, is one of the full validation's
    modules = sorted(f"tactilepipe.{p.parent.name}.checks" for p in (REPO / "src" / "tactilepipe").glob("*/checks.py"))
    assert modules == ["tactilepipe.papillarray.checks", "tactilepipe.tool.checks", "tactilepipe.volume.checks"]
    assert sorted(c.__module__ for c in studies.CHECKS) == modules
    common = (REPO / "workflow" / "rules" / "common.smk").read_text()
    assert 'P = resolve(dict(config), "params.yaml (+ --config)", OVERRIDES, studies.CHECKS)' in common


def test_a_command_that_reads_parameters_must_name_its_checks():
    with pytest.raises(TactilepipeError, match="declares no checks="):
        command("no-such-stage", "a stage without checks", params=("seed",))(lambda args, p: None)
