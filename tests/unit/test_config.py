"""params.yaml + schema: every scale loads, every kind of mistake is a ConfigError naming the key
(also through the CLI: exit code 2 and one line); atomic output writing."""

from __future__ import annotations

import json

import pytest
import yaml

from tactilepipe.cli import main as cli
from tactilepipe.core.atomic import atomic_path, write_json, write_text
from tactilepipe.core.config import deep_merge
from tactilepipe.core.errors import ConfigError
from tactilepipe.studies import load_params      # as the workflow validates: every study's checks

from support.hostile import billion_laughs


@pytest.fixture(scope="module")
def raw_params(params_path) -> dict:
    return yaml.safe_load(params_path.read_text())


# --- loading -----------------------------------------------------------------------------------

def test_every_scale_loads(params_path, raw_params):
    assert set(raw_params["scales"]) >= {"smoke", "default", "paper"}
    for scale in raw_params["scales"]:
        p = load_params(params_path, {"scale": scale})
        assert p["scale"] == scale
        assert "scales" not in p
        assert p["volume_sessions"] == [f"sim-{scale}"]        # "{scale}" is filled in
        need = p["folds"]["train_lifts_per_volume"] + p["folds"]["test_lifts_per_volume"]
        assert p["simulate_volume"]["lifts_per_volume"] >= need


def test_scale_overlay_is_applied(params_path, raw_params):
    smoke = load_params(params_path, {"scale": "smoke"})
    default = load_params(params_path, {"scale": "default"})
    assert smoke["simulate_volume"]["rate_hz"] == 100 and default["simulate_volume"]["rate_hz"] == 500
    assert smoke["mlp"]["grid"]["inner_folds"] == 2
    assert smoke["mlp"]["grid"]["modality"] == raw_params["mlp"]["grid"]["modality"]   # deep merge keeps siblings
    assert smoke["simulate_volume"]["container_mass_g"] == default["simulate_volume"]["container_mass_g"]


def test_overrides_are_merged_before_validation(params_path):
    p = load_params(params_path, {"scale": "default", "seed": 7, "baseline": {"n_mu": 11}})
    assert p["seed"] == 7 and p["baseline"]["n_mu"] == 11 and p["baseline"]["mu_min"] == 0.1


def test_deep_merge_does_not_touch_its_inputs():
    base = {"a": {"b": 1, "c": [1, 2]}, "d": 1}
    over = {"a": {"b": 2}, "e": {"f": 3}}
    out = deep_merge(base, over)
    assert out == {"a": {"b": 2, "c": [1, 2]}, "d": 1, "e": {"f": 3}}
    assert base == {"a": {"b": 1, "c": [1, 2]}, "d": 1} and over == {"a": {"b": 2}, "e": {"f": 3}}
    out["a"]["c"].append(3)
    assert base["a"]["c"] == [1, 2]


# --- mistakes --------------------------------------------------------------------------------------

BAD = [
    ("wrong_type_top", {"seed": "abc"}, r"invalid parameter at 'seed': 'abc' is not of type 'integer'"),
    ("negative_seed", {"seed": -1}, r"at 'seed'"),
    ("huge_seed", {"seed": 2**70}, r"at 'seed': 1180591620717411303424 is greater than the maximum of 4294967295"),
    ("wrong_type_nested", {"folds": {"n_folds": 2.5}}, r"at 'folds.n_folds'"),
    ("wrong_enum_nested", {"simulate_volume": {"rate_hz": 123}}, r"at 'simulate_volume.rate_hz': 123 is not one of"),
    ("list_expected", {"simulate_volume": {"volumes_ml": 100}}, r"at 'simulate_volume.volumes_ml'"),
    ("unknown_top_key", {"bogus_key": 1}, r"'bogus_key' was unexpected"),
    ("unknown_nested_key", {"mlp": {"hiden_units": 4}}, r"at 'mlp'.*'hiden_units' was unexpected"),
    ("unknown_deep_key", {"mlp": {"grid": {"alphas": [1.0]}}}, r"at 'mlp.grid'.*'alphas' was unexpected"),
    ("unknown_key_in_scale", {"scales": {"smoke": {"folds": {"n_fold": 2}}}},
     r"at 'scales.smoke.folds'.*'n_fold' was unexpected"),
    ("wrong_type_in_scale", {"scales": {"smoke": {"simulate_volume": {"lifts_per_volume": "five"}}}},
     r"at 'scales.smoke.simulate_volume.lifts_per_volume'"),
    ("unknown_scale", {"scale": "huge"}, r"unknown scale 'huge' \(choose one of \['default', 'paper', 'smoke'\]\)"),
    ("too_few_lifts", {"scale": "default", "simulate_volume": {"lifts_per_volume": 12}},
     r"simulate_volume.lifts_per_volume=12 is fewer than the 14 lifts per volume the folds need"),
    ("too_few_lifts_in_scale", {"scale": "smoke", "scales": {"smoke": {"simulate_volume": {"lifts_per_volume": 4}}}},
     r"simulate_volume.lifts_per_volume=4 is fewer than the 5"),
    ("mu_equal", {"baseline": {"mu_min": 0.3, "mu_max": 0.3}}, r"baseline.mu_min must be below baseline.mu_max"),
    ("mu_reversed", {"baseline": {"mu_min": 0.4, "mu_max": 0.1}}, r"baseline.mu_min must be below baseline.mu_max"),
    ("grid_modality", {"mlp": {"grid": {"modality": "fxyz"}}}, r"mlp.grid.modality 'fxyz' is not one of mlp.modalities"),
    ("kinetic_above_static", {"simulate_volume": {"friction_static": 0.3, "friction_kinetic": 0.5}},
     r"simulate_volume.friction_kinetic must not exceed friction_static"),
    ("bad_modality_axis", {"mlp": {"modalities": {"fw": ["fw"]}}}, r"at 'mlp.modalities.fw.0'"),
]


@pytest.mark.parametrize("name, overrides, problem", BAD, ids=[b[0] for b in BAD])
def test_bad_parameters_raise_config_error_naming_the_key(params_path, name, overrides, problem):
    with pytest.raises(ConfigError, match=problem) as err:
        load_params(params_path, overrides)
    assert str(err.value).startswith(str(params_path))
    assert "\n" not in str(err.value)


def test_missing_required_group(tmp_path, raw_params):
    bad = dict(raw_params)
    del bad["segment"]
    path = tmp_path / "p.yaml"
    path.write_text(yaml.safe_dump(bad))
    with pytest.raises(ConfigError, match=r"'segment' is a required property"):
        load_params(path)


@pytest.mark.parametrize("text, problem", [("", "expected a mapping"), ("- 1\n- 2\n", "expected a mapping"),
                                           ("seed: [1, 2\n", "not valid YAML")])
def test_unusable_files(tmp_path, text, problem):
    path = tmp_path / "p.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=problem):
        load_params(path)
    with pytest.raises(ConfigError, match="parameter file not found"):
        load_params(tmp_path / "absent.yaml")


# --- aliases: bounded before anything is built -------------------------------------------------------

def test_modest_anchors_load_and_are_counted_expanded():
    from tactilepipe.core.yamlsafe import expanded_nodes, load_yaml_text
    text = "base: &b {lr: 0.001, layers: [8, 16]}\na: *b\nb: *b\n"
    assert expanded_nodes(text, "t.yaml") == 1 + 3 * (1 + 7)            # the root, three keys, three blocks of 7
    assert load_yaml_text(text, "t.yaml")["b"] == {"lr": 0.001, "layers": [8, 16]}


def test_a_billion_laughs_params_file_is_refused_naming_the_file(tmp_path):
    import time
    from tactilepipe.core.yamlsafe import expanded_nodes
    path = tmp_path / "params.yaml"
    path.write_text(billion_laughs())
    assert len(path.read_bytes()) < 600
    start = time.perf_counter()
    with pytest.raises(ConfigError, match=r"params\.yaml: its anchors and aliases expand to more than 200,000 nodes"):
        load_params(path)
    assert time.perf_counter() - start < 5
    with pytest.raises(ConfigError, match="alias \\*a refers to a node that contains it"):
        expanded_nodes("a: &a [1, *a]\n", "r.yaml")


# --- through the CLI -----------------------------------------------------------------------------

def _split(tmp_path, params, *extra):
    out = tmp_path / "folds.json"
    return out, ["volume-split", "--params", str(params), "--dataset", str(tmp_path / "data.parquet"),
                 "--out", str(out), *extra]


def _assert_one_line_error(capsys, *needles):
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("tactilepipe volume-split: error: ")
    for needle in needles:
        assert needle in lines[0], lines[0]
    assert "Traceback" not in captured.err


@pytest.mark.parametrize("change, needle", [
    ({"seed": "abc"}, "'seed'"),
    ({"folds": {"n_folds": 0}}, "'folds.n_folds'"),
    ({"baseline": {"mu_min": 0.5}}, "baseline.mu_min"),
    ({"unknown": 1}, "'unknown' was unexpected"),
])
def test_cli_split_with_bad_params_exits_2_with_one_line(tmp_path, raw_params, capsys, change, needle):
    params = tmp_path / "bad.yaml"
    params.write_text(yaml.safe_dump(deep_merge(raw_params, change)))
    out, argv = _split(tmp_path, params)
    assert cli.main(argv) == 2
    _assert_one_line_error(capsys, str(params), needle)
    assert not out.exists()


def test_cli_split_with_missing_params_file(tmp_path, capsys):
    out, argv = _split(tmp_path, tmp_path / "nope.yaml")
    assert cli.main(argv) == 2
    _assert_one_line_error(capsys, "nope.yaml", "not found")


def test_cli_split_with_bad_override(tmp_path, params_path, capsys):
    out, argv = _split(tmp_path, params_path, "--override", json.dumps({"scale": "gigantic"}))
    assert cli.main(argv) == 2
    _assert_one_line_error(capsys, "unknown scale 'gigantic'")


def test_cli_split_with_yaml_syntax_error_prints_one_line(tmp_path, capsys):
    params = tmp_path / "broken.yaml"
    params.write_text("seed: [1, 2\nscale: smoke\n")
    out, argv = _split(tmp_path, params)
    assert cli.main(argv) == 2
    _assert_one_line_error(capsys, "broken.yaml", "not valid YAML", "line 2")


def test_cli_split_with_malformed_override_json(tmp_path, params_path, capsys):
    out, argv = _split(tmp_path, params_path, "--override", "{scale: smoke")
    assert cli.main(argv) == 2
    _assert_one_line_error(capsys, "--override")


# --- atomic outputs ----------------------------------------------------------------------------

def test_atomic_path_failure_leaves_nothing(tmp_path):
    target = tmp_path / "out" / "result.json"
    with pytest.raises(RuntimeError, match="boom"):
        with atomic_path(target) as tmp:
            assert tmp.parent == target.parent and tmp != target
            tmp.write_text("half written")
            raise RuntimeError("boom")
    assert not target.exists()
    assert list(target.parent.iterdir()) == []


def test_atomic_path_failure_keeps_the_old_target(tmp_path):
    target = tmp_path / "result.txt"
    target.write_text("old")
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(target) as tmp:
            tmp.write_text("new but interrupted")
            raise KeyboardInterrupt
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["result.txt"]


def test_atomic_writes_replace_the_target(tmp_path):
    target = tmp_path / "a" / "b.json"
    write_json(target, {"z": 1, "a": [1, 2]})
    assert json.loads(target.read_text()) == {"z": 1, "a": [1, 2]}
    write_text(target, "replaced\n")
    assert target.read_text() == "replaced\n"
    assert [p.name for p in target.parent.iterdir()] == ["b.json"]


def test_an_explicit_override_wins_over_the_scale_overlay(params_path):
    p = load_params(params_path, {"scale": "smoke", "simulate_volume": {"rate_hz": 500}})
    assert p["simulate_volume"]["rate_hz"] == 500
    assert p["simulate_volume"]["lifts_per_volume"] == 5          # the rest of the overlay still applies


def test_atomic_outputs_get_the_usual_file_mode(tmp_path):
    import os
    from tactilepipe.core.atomic import write_text
    write_text(tmp_path / "a.txt", "x")
    umask = os.umask(0)
    os.umask(umask)
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o666 & ~umask


# --- a stage's declared parameters -------------------------------------------------------------------

def test_a_stage_receives_only_the_keys_it_declares():
    from tactilepipe.core.config import declared
    resolved = {"scale": "smoke", "mlp": {"max_iter": 60, "grid": {"alpha": [1e-4]}}, "seed": 7}
    p = declared(resolved, ["scale", "mlp.grid"], "cmd_x")
    assert p == {"scale": "smoke", "mlp": {"grid": {"alpha": [1e-4]}}}
    assert p["mlp"]["grid"]["alpha"] == [1e-4]
    with pytest.raises(ConfigError, match=r"cmd_x: reads parameter 'seed', which the stage does not declare "
                                          r"\(add it to the params= of the stage's @command declaration in tactilepipe.cli\)"):
        p["seed"]
    with pytest.raises(ConfigError, match="cmd_x: reads parameter 'max_iter'"):
        p["mlp"]["max_iter"]                       # a sibling of a declared key is not declared
    with pytest.raises(ConfigError, match="reads parameter 'seed'"):
        p.get("seed", 2026)                        # no silent fallback default either
    p["mlp"]["grid"]["alpha"].append(1.0)           # a copy: the resolved parameters stay as they were
    assert resolved["mlp"]["grid"]["alpha"] == [1e-4]


def test_declaring_a_key_that_params_yaml_lacks_is_an_error():
    from tactilepipe.core.config import declared
    with pytest.raises(ConfigError, match="cmd_x: declares parameter 'mlp.epochs', which params.yaml does not have"):
        declared({"mlp": {"max_iter": 60}}, ["mlp.epochs"], "cmd_x")


def test_the_cli_hands_a_stage_its_declared_parameters_only(tmp_path):
    args = cli.build_parser().parse_args(["volume-report", "--in-dir", str(tmp_path)])
    from tactilepipe.cli.common import stage_params
    p = stage_params(args, "scale")
    with pytest.raises(ConfigError, match="reads parameter 'seed'"):
        p["seed"]


def test_nested_config_text_takes_the_type_params_yaml_has(raw_params):
    from tactilepipe.core.config import typed_like
    # what Snakemake makes of --config folds='{"n_folds": 2}' tool_train='{"variants": "[full]"}'
    given = {"folds": {"n_folds": "2"}, "tool_train": {"variants": "[full]", "kernels": "native"}, "seed": 7}
    typed = typed_like(given, raw_params)
    assert typed == {"folds": {"n_folds": 2}, "tool_train": {"variants": ["full"], "kernels": "native"}, "seed": 7}
    assert typed_like({"folds": {"n_folds": "two"}}, raw_params) == {"folds": {"n_folds": "two"}}   # left to validation
    assert typed_like({"tool_train": {"lr": "1e-4"}}, raw_params) == {"tool_train": {"lr": 1e-4}}  # YAML 1.1 reads text
    assert typed_like({"tool_train": {"sweep": [{"depth": "34", "image_size": "8"}]}}, raw_params) == \
        {"tool_train": {"sweep": [{"depth": 34, "image_size": 8}]}}


def test_an_override_keeps_only_the_keys_that_changed(raw_params):
    from tactilepipe.core.config import changed_leaves
    merged = {**raw_params, "folds": {**raw_params["folds"], "n_folds": 3}, "scale": "smoke"}   # as Snakemake merges
    assert changed_leaves(merged, raw_params) == {"folds": {"n_folds": 3}, "scale": "smoke"}
    assert changed_leaves(raw_params, raw_params) == {}


def test_a_model_input_larger_than_the_stored_frames_is_refused(params_path):
    with pytest.raises(ConfigError, match=r"tool_train.image_size=96 is larger than tool_ingest.stored_size=64"):
        load_params(params_path, {"scale": "default", "tool_train": {"image_size": 96}})
    with pytest.raises(ConfigError, match=r"tool_train.sweep\[0\].image_size=128 is larger"):
        load_params(params_path, {"scale": "default", "tool_train": {"sweep": [{"depth": 18, "image_size": 128}]}})


def test_portable_kernels_on_more_threads_or_a_gpu_are_refused_before_any_job(params_path):
    # the workflow validates params.yaml with every study's checks at its start, so `snakemake -n`
    # refuses these instead of every training or estimating job failing
    for group, extra in (("tool_train", {}), ("predict", {})):
        with pytest.raises(ConfigError, match=rf"{group}.num_threads 2 with kernels: portable"):
            load_params(params_path, {"scale": "default", group: {"kernels": "portable", "num_threads": 2, **extra}})
    with pytest.raises(ConfigError, match=r"tool_train.kernels: portable pins CPU kernels, but the run is on cuda"):
        load_params(params_path, {"scale": "default", "tool_train": {"kernels": "portable", "device": "cuda"}})
    ok = load_params(params_path, {"scale": "default", "tool_train": {"kernels": "native", "num_threads": 2,
                                                                      "device": "cuda"}})
    assert ok["tool_train"]["num_threads"] == 2


def test_a_stage_under_the_workflow_takes_its_values_from_its_stamp(tmp_path, capsys, monkeypatch):
    """The values a job receives are its stamp's, not params.yaml's; a stamp of another stage, or
    --stamp with --override, is refused in one line."""
    import pandas as pd
    from tactilepipe.cli.common import stage_params
    data = tmp_path / "data.parquet"
    pd.DataFrame({"lift": ["a"], "volume_ml": [0.0], "set": ["main"]}).to_parquet(data)
    values = {"seed": 11, "folds": {"n_folds": 2, "train_lifts_per_volume": 3, "test_lifts_per_volume": 2}}
    stamp = tmp_path / "volume-split.json"
    stamp.write_text(json.dumps({"stage": "volume-split", "declared": ["seed", "folds"], "graph": [], "values": values}))
    args = cli.build_parser().parse_args(["volume-split", "--stamp", str(stamp), "--dataset", str(data), "--out", "x"])
    assert stage_params(args, "seed", "folds") == values
    other = tmp_path / "volume-train.json"
    other.write_text(json.dumps({"stage": "volume-train", "declared": [], "graph": [], "values": values}))
    assert cli.main(["volume-split", "--stamp", str(other), "--dataset", str(data), "--out", "x"]) == 2
    assert "not the parameter stamp of volume-split (it names 'volume-train')" in capsys.readouterr().err
    assert cli.main(["volume-split", "--stamp", str(stamp), "--override", "{}", "--scale", "smoke",
                     "--dataset", str(data), "--out", "x"]) == 2
    assert "give it without --override or --scale" in capsys.readouterr().err
