"""The parameter models and the JSON schema generated from them: the committed schema is what the
models give, it is the one file config validates with, and a scale overlay takes any part of any
group (nested groups too) and nothing else."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from tactilepipe.core.config import PARAMS_SCHEMA, load_params
from tactilepipe.core.errors import ConfigError
from tactilepipe.core.parameters.params_file import Params, ScaleOverlay
from tactilepipe.core.parameters.base import Group
from tactilepipe.core.parameters.schema import params_schema

from support.project import BIN, REPO, run

SCRIPT = "workflow/scripts/params_schema.py"


# --- the generated schema --------------------------------------------------------------------------

def test_the_committed_schema_is_what_the_models_give():
    proc = run([str(BIN / "python"), SCRIPT, "--check"], REPO, check=False)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]


def test_a_stale_schema_is_refused_with_what_differs(tmp_path):
    stale = tmp_path / "params.schema.json"
    text = Path(str(PARAMS_SCHEMA)).read_text()
    line = '"lifts_per_volume": {"description": "at most 10000 per volume", "maximum": 10000, "minimum": 1, ' \
           '"type": "integer"}'
    assert line in text
    stale.write_text(text.replace(line, line.replace('"minimum": 1', '"minimum": 2'), 1))
    proc = run([str(BIN / "python"), SCRIPT, "--check", "--out", str(stale)], REPO, check=False)
    assert proc.returncode == 1
    assert '-        ' + line.replace('"minimum": 1', '"minimum": 2') in proc.stdout
    assert '+        ' + line in proc.stdout
    assert "run `make schema`" in proc.stdout
    assert stale.read_text() != text                  # --check never writes


def test_the_schema_is_one_file_shipped_with_the_package():
    assert (REPO / "workflow/schemas/params.schema.json").is_symlink()
    assert (REPO / "workflow/schemas/params.schema.json").resolve() == Path(str(PARAMS_SCHEMA)).resolve()
    assert Path(str(PARAMS_SCHEMA)).resolve() == (REPO / "src/tactilepipe/core/params.schema.json").resolve()
    package_data = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    assert "params.schema.json" in package_data["tactilepipe.core"]


# --- the scale overlays ----------------------------------------------------------------------------

def _groups(model: type[Group]) -> set[str]:
    return {name for name, f in model.model_fields.items()
            if isinstance(f.annotation, type) and issubclass(f.annotation, Group)}


def test_a_scale_may_overlay_every_group_and_nothing_else():
    assert set(ScaleOverlay.model_fields) == _groups(Params)
    assert {"scenes", "scale", "seed", "volume_sessions", "scales"}.isdisjoint(ScaleOverlay.model_fields)


def test_each_overlay_has_its_groups_keys_and_constraints_none_required():
    defs = params_schema()["$defs"]
    # the groups the schema holds whole and as an overlay (a few exist only as overlays)
    groups = {name[:-len("Overlay")] for name in defs if name.endswith("Overlay")} & defs.keys()
    assert {"SimulateVolume", "PositionGrip", "Mlp", "MlpGrid", "ToolTrain", "DigitRender", "JobResources"} <= groups
    for group in groups:
        whole, overlay = defs[group], defs[f"{group}Overlay"]
        assert "required" not in overlay, group
        assert overlay["additionalProperties"] is False, group
        assert overlay["properties"].keys() == whole["properties"].keys(), group
        for key, schema in whole["properties"].items():
            # a nested group's key refers to that group's overlay (an overlay is its own); every
            # other key is as in the group
            expected = schema
            if "$ref" in schema and not schema["$ref"].endswith("Overlay"):
                expected = {**schema, "$ref": schema["$ref"] + "Overlay"}
            assert overlay["properties"][key] == expected, (group, key)


def test_an_overlay_gives_part_of_a_nested_group(params_path):
    p = load_params(params_path, {"scale": "smoke",
                                  "scales": {"smoke": {"simulate_volume": {"position": {"squeeze_mm": 10.0}}}}})
    default = load_params(params_path)
    assert p["simulate_volume"]["position"]["squeeze_mm"] == 10.0
    assert {k: v for k, v in p["simulate_volume"]["position"].items() if k != "squeeze_mm"} == \
        {k: v for k, v in default["simulate_volume"]["position"].items() if k != "squeeze_mm"}
    assert p["simulate_volume"]["rate_hz"] == 100                  # the rest of the smoke overlay still applies


def test_an_overlay_reads_yaml_1_1_exponents_as_numbers(params_path):
    p = load_params(params_path, {"scale": "smoke", "scales": {"smoke": {"mlp": {"alpha": "1e-4"}}}})
    assert p["mlp"]["alpha"] == 1e-4


OVERLAY_MISTAKES = [
    ("unknown_nested_key", {"smoke": {"simulate_volume": {"position": {"squeeze": 1.0}}}},
     r"at 'scales.smoke.simulate_volume.position': Additional properties are not allowed \('squeeze' was unexpected\)"),
    ("unknown_group", {"paper": {"tool_trian": {"lr": 0.1}}}, r"at 'scales.paper': .*'tool_trian' was unexpected"),
    ("top_level_value", {"paper": {"seed": 1}}, r"at 'scales.paper': .*'seed' was unexpected"),
    ("null_key", {"smoke": {"folds": {"n_folds": None}}}, r"at 'scales.smoke.folds.n_folds': None is not of type 'integer'"),
    ("out_of_range", {"smoke": {"folds": {"n_folds": 0}}}, r"at 'scales.smoke.folds.n_folds': 0 is less than the minimum of 1"),
    ("list_item_stays_whole", {"smoke": {"tool_train": {"sweep": [{"depth": 18}]}}},
     r"at 'scales.smoke.tool_train.sweep.0': 'image_size' is a required property"),
    ("unknown_rule", {"paper": {"resources": {"rules": {"tool_trian": {"gpu": 1}}}}},
     r"at 'scales.paper.resources.rules': .*'tool_trian' was unexpected"),
]


@pytest.mark.parametrize("name, scales, problem", OVERLAY_MISTAKES, ids=[m[0] for m in OVERLAY_MISTAKES])
def test_an_overlay_refuses_what_its_group_refuses_naming_the_key(params_path, name, scales, problem):
    with pytest.raises(ConfigError, match=problem) as err:
        load_params(params_path, {"scales": scales})
    assert str(err.value).startswith(f"{params_path}: invalid parameter at 'scales.")


# --- finite and bounded ----------------------------------------------------------------------------

def _integers(node, path=""):
    """(path, schema) of every integer the schema declares (enumerations aside)."""
    if isinstance(node, dict):
        if node.get("type") == "integer" and "enum" not in node:
            yield path, node
        for key, value in node.items():
            yield from _integers(value, f"{path}/{key}")
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from _integers(value, f"{path}/{i}")


def test_every_count_and_size_has_an_upper_bound():
    integers = list(_integers(params_schema()))
    assert len(integers) > 40
    assert [path for path, schema in integers if "maximum" not in schema] == []


def test_a_nan_or_infinite_number_is_refused_wherever_it_stands(tmp_path):
    with pytest.raises(ConfigError, match=r"at 'tool_train.lr': nan is not a finite number"):
        load_params(overrides={"tool_train": {"lr": float("nan")}})
    with pytest.raises(ConfigError, match=r"at 'mlp.grid.learning_rate.1': inf is not a finite number"):
        load_params(overrides={"mlp": {"grid": {"learning_rate": [1e-3, float("inf")]}}})
    with pytest.raises(ConfigError, match=r"at 'scales.smoke.drift.tolerance_n': -inf is not a finite number"):
        load_params(overrides={"scales": {"smoke": {"drift": {"tolerance_n": float("-inf")}}}})


@pytest.mark.parametrize("edit, needle", [
    (("  lr: ", "  lr: .nan  #"), "invalid parameter at 'tool_train.lr': nan is not a finite number"),
    (("  repeats: ", "  repeats: 1000000000  #"),
     "invalid parameter at 'tool_split.repeats': 1000000000 is greater than the maximum of 100"),
], ids=["nan_learning_rate", "a_billion_repeats"])
def test_the_command_line_refuses_a_nan_rate_and_a_billion_repeats_in_one_line(tmp_path, capsys, edit, needle):
    """The YAML a user writes: before, the NaN rate reached torch's optimizer (ValueError) and the
    billion repeats passed the schema and the workflow's planning ran out of memory."""
    from tactilepipe.cli.main import main
    text = (REPO / "params.yaml").read_text()
    old, new = edit
    start = text.index(old, text.index("\ntool_train:" if "lr" in old else "\ntool_split:"))
    params = tmp_path / "params.yaml"
    params.write_text(text[:start] + new + text[start + len(old):])
    status = main(["tool-train", "--params", str(params), "--scene", "tool_normal", "--run", "full",
                   "--data-dir", str(tmp_path / "data"), "--split", str(tmp_path / "s.json"),
                   "--out-dir", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1, err
    assert err.startswith("tactilepipe tool-train: error: ") and needle in err, err
    assert not (tmp_path / "out").exists()
