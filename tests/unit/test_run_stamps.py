"""A training job's stamp holds exactly what the job reads; model variants are parameters.

The stamps are made here the way the workflow makes them (pipeline/stamp_keeper.py StampKeeper.run); the
workflow tests (integration/test_workflow.py) check what Snakemake plans when one changes."""

from __future__ import annotations

import json
from typing import get_args

import pytest

from tactilepipe.core.errors import ConfigError, InputError
from tactilepipe.pipeline import codedeps, stamps
from tactilepipe.studies import load_params      # as the workflow validates: every study's checks
from tactilepipe.tool import runs
from tactilepipe.core.tool_vocabulary import BASELINES
from tactilepipe.tool.model.variants import NAMED_ARCHITECTURES, Architecture, defined_variants

from support.project import REPO

SMOKE = {"scale": "smoke"}


def run_stamp(p: dict, run: str) -> dict:
    """The stamp the workflow writes for ``run`` under the resolved parameters ``p``."""
    text = stamps.run_stamp_text(runs.run_definition(p, run), codedeps.stage_param_keys("tool-train"),
                                 codedeps.stage_graph_keys("tool-train"), runs.run_source_keys(p["tool_train"], run), p)
    return json.loads(text)


def _leaves(node, prefix=""):
    if isinstance(node, dict):
        return {k for key, sub in node.items() for k in _leaves(sub, f"{prefix}{key}.")}
    return {prefix[:-1]}


def test_a_sweep_runs_stamp_holds_its_own_depth_and_size_and_not_the_image_size_it_never_reads():
    p = load_params(REPO / "params.yaml", SMOKE)
    sweep = runs.sweep_run_name(p["tool_train"]["sweep"][0])              # full_d18_s8
    stamp = run_stamp(p, sweep)
    assert stamp["stage"] == "tool-train" and stamp["run"] == sweep
    run = stamp["values"]["run"]
    assert (run["depth"], run["image_size"]) == (18, 8) and run["split"] == p["tool_train"]["split"]
    assert run["variant"] == {"name": "full", "sensors": [[0, 2], [2, 4]], "gam": True}
    keys = _leaves(stamp["values"])
    assert not any(k.startswith(("tool_train.image_size", "tool_train.depth", "tool_train.variants",
                                 "tool_train.sweep", "tool_train.loto", "tool_variants")) for k in keys), keys
    assert {"seed", "tool_train.lr", "tool_train.width", "tool_train.kernels"} <= keys
    # a new image size re-stamps the runs that read it, never the sweep run
    other = load_params(REPO / "params.yaml", {**SMOKE, "tool_train": {"image_size": 24}})
    assert run_stamp(other, sweep) == stamp
    assert run_stamp(other, "full")["values"]["run"]["image_size"] == 24 != run_stamp(p, "full")["values"]["run"]["image_size"]
    # a training setting re-stamps every run
    faster = load_params(REPO / "params.yaml", {**SMOKE, "tool_train": {"lr": 0.001}})
    assert all(run_stamp(faster, r) != run_stamp(p, r) for r in ("full", "no_ref_r1", sweep, "full_loto_spatula"))


def test_a_variants_stamp_holds_its_definition_and_another_variant_leaves_it_alone():
    p = load_params(REPO / "params.yaml", SMOKE)
    stamp = run_stamp(p, "no_ref_r1")
    assert stamp["values"]["run"] == {"name": "no_ref_r1", "variant": {"name": "no_ref", "sensors": [[0, 1], [2, 3]],
                                                                         "gam": True},
                                      "split": "trial_r1", "depth": 18, "image_size": 16}
    assert stamp["graph"] == ["tool_variants.no_ref", "tool_train.split", "tool_train.depth", "tool_train.image_size"]
    extra = dict(p["tool_variants"]["no_gam"], label="copy")
    more = load_params(REPO / "params.yaml", {**SMOKE, "tool_variants": {"no_gam_copy": extra}})
    assert more["tool_train"]["variants"] == ["full", "no_ref", "single", "no_gam", "no_gam_copy"]    # file order
    assert run_stamp(more, "no_ref_r1") == stamp
    assert run_stamp(more, "no_gam_copy_r1")["values"]["run"]["variant"] == {"name": "no_gam_copy",
                                                                              "sensors": [[0, 2], [2, 4]], "gam": False}
    # what only the report reads (label, colour, baseline) is not in a run's stamp
    relabelled = load_params(REPO / "params.yaml", {**SMOKE, "tool_variants": {"no_ref": dict(
        p["tool_variants"]["no_ref"], label="other", colour="#000000")}})
    assert run_stamp(relabelled, "no_ref_r1") == stamp


def test_a_run_stamp_is_read_back_and_a_stage_stamp_is_refused_as_one(tmp_path):
    p = load_params(REPO / "params.yaml", SMOKE)
    path = tmp_path / "full.json"
    path.write_text(json.dumps(run_stamp(p, "full")))
    assert stamps.run_of_stamp(path) == runs.run_definition(p, "full")
    stage = tmp_path / "tool-train.json"
    stage.write_text(stamps.stamp_text("tool-train", codedeps.stage_param_keys("tool-train"), (), p))
    with pytest.raises(InputError, match="not a training run's stamp"):
        stamps.run_of_stamp(stage)


def test_the_cli_trains_what_the_stamp_says_and_refuses_a_stage_stamp_in_one_line(tmp_path, capsys, monkeypatch):
    from tactilepipe.cli.main import main
    from tactilepipe.tool.model import run as run_mod
    # native kernels: portable ones must be chosen before torch loads, and other tests load it in this process
    p = load_params(REPO / "params.yaml", {**SMOKE, "tool_train": {"kernels": "native"}})
    seen = {}
    monkeypatch.setattr(run_mod, "train_and_predict", lambda *a, **k: seen.setdefault("args", a) and {})
    good = tmp_path / "single_r1.json"
    good.write_text(json.dumps(run_stamp(p, "single_r1")))
    args = ["--scene", "tool_normal", "--data-dir", str(tmp_path), "--split", str(tmp_path / "s.json"),
            "--out-dir", str(tmp_path / "out"), "--quiet"]
    with pytest.raises(KeyError):                 # the stand-in returns no metrics: past the point that matters
        main(["tool-train", "--stamp", str(good), *args])
    assert seen["args"][4] == runs.run_definition(p, "single_r1")
    assert seen["args"][5]["lr"] == p["tool_train"]["lr"]
    stage = tmp_path / "stage.json"
    stage.write_text(stamps.stamp_text("tool-train", codedeps.stage_param_keys("tool-train"), (), p))
    assert main(["tool-train", "--stamp", str(stage), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not a training run's stamp" in err, err
    assert main(["tool-train", "--scale", "smoke", *args]) == 2
    assert "--run NAME" in capsys.readouterr().err


def test_the_four_variants_keep_their_definitions_and_their_baselines_are_the_reports():
    from tactilepipe.core.parameters.tool import Baseline
    assert sorted(get_args(Baseline)) == sorted(BASELINES)
    defined = defined_variants(load_params(REPO / "params.yaml")["tool_variants"])
    assert {n: v.architecture for n, v in defined.items()} == NAMED_ARCHITECTURES
    assert {n: v.baseline for n, v in defined.items()} == {"full": "tactile_rmse_linear", "no_ref": "rest_frame_rmse_linear",
                                                          "single": "one_finger_rmse_linear",
                                                          "no_gam": "tactile_rmse_linear"}


@pytest.mark.parametrize("overrides, problem", [
    ({"tool_train": {"variants": ["full", "tiny"]}}, r"tool_train.variants: unknown variant\(s\) \['tiny'\]"),
    ({"tool_variants": {"no_gam_r2": {}}}, "the name reads as another run"),
    ({"tool_variants": {"full_small": {}}}, "the name reads as another run"),
    ({"tool_variants": {"full": {"sensors": [[2, 2]]}}}, r"tool_variants.full.sensors: \[2, 2\] is no channel slice"),
    ({"tool_variants": {"wide": {"sensors": [[0, 5]]}}}, "invalid parameter at 'tool_variants.wide.sensors.0.1'"),
    ({"tool_variants": {"Bad-Name": {}}}, "invalid parameter at 'tool_variants'"),
], ids=["unknown", "repeat_suffix", "full_prefix", "empty_slice", "past_the_channels", "name"])
def test_a_variant_the_runs_cannot_name_or_the_network_cannot_build_is_refused(overrides, problem):
    p = load_params(REPO / "params.yaml")
    entry = dict(p["tool_variants"]["no_gam"])
    for name, given in overrides.get("tool_variants", {}).items():
        overrides["tool_variants"][name] = {**entry, **given}
    with pytest.raises(ConfigError, match=problem):
        load_params(REPO / "params.yaml", overrides)


def test_params_yaml_must_define_the_full_model():
    import yaml
    raw = yaml.safe_load((REPO / "params.yaml").read_text())
    del raw["tool_variants"]["full"]
    raw["tool_train"]["variants"] = ["no_gam"]
    from tactilepipe.studies import resolve
    with pytest.raises(ConfigError, match="tool_variants must define 'full'"):
        resolve(raw)


def test_a_checkpoint_of_a_new_variant_loads_on_its_own_and_an_old_one_by_its_name(tmp_path):
    import torch
    from tactilepipe.tool.model.checkpoint import CHECKPOINT_FORMAT
    from tactilepipe.tool.model.inference import load_model
    from tactilepipe.tool.model.network import build_model
    arch = Architecture(((1, 2), (3, 4)), False)               # no name of NAMED_ARCHITECTURES builds this
    meta = {"variant": "refs_only", "architecture": arch.as_dict(), "depth": 18, "image_size": 16,
            "gam_channel_gate": "sigmoid", "width": 4, "normalise": "minmax", "label_stats": {"min": 0, "max": 1}}
    model = build_model("refs_only", 18, 16, "sigmoid", 4, arch)
    torch.save({"format": CHECKPOINT_FORMAT, "model": model.state_dict(), "meta": meta, "config": {}}, tmp_path / "new.pt")
    loaded, got = load_model(tmp_path / "new.pt", channels_last=False)
    assert loaded.architecture == arch and got["variant"] == "refs_only"
    old = {k: v for k, v in meta.items() if k != "architecture"}        # written when only the name was recorded
    torch.save({"format": CHECKPOINT_FORMAT, "model": model.state_dict(), "meta": old, "config": {}}, tmp_path / "old.pt")
    with pytest.raises(InputError, match="metadata: unknown model variant 'refs_only'"):
        load_model(tmp_path / "old.pt")
    full = build_model("full", 18, 16, "sigmoid", 4)
    torch.save({"format": CHECKPOINT_FORMAT, "model": full.state_dict(), "meta": {**old, "variant": "full"}, "config": {}},
               tmp_path / "old_full.pt")
    assert load_model(tmp_path / "old_full.pt")[0].architecture == NAMED_ARCHITECTURES["full"]
