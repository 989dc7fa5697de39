"""The variance decomposition of paired MAE differences (tool/report/noise.py), on draws whose
components are known: each is recovered, and the design half-widths follow the stated model."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tactilepipe.core.errors import TactilepipeError
from tactilepipe.tool.report.noise import bootstrap_difference_variance, decompose, half_width


def test_seed_and_split_components_are_recovered_from_draws_with_known_spreads():
    rng = np.random.default_rng(1)
    splits, seeds = 400, 4
    split_effect = rng.normal(0.0, 0.3, size=(splits, 1))     # sd 0.3 between splits
    seed_noise = rng.normal(0.0, 0.1, size=(splits, seeds))    # sd 0.1 between seeds
    parts = decompose(0.5 + split_effect + seed_noise, np.full((splits, seeds), 0.02), 0.24)
    assert parts["mean"] == pytest.approx(0.5, abs=0.04)
    assert math.sqrt(parts["var_seed"]) == pytest.approx(0.1, rel=0.08)
    assert math.sqrt(parts["var_split"]) == pytest.approx(0.3, rel=0.1)
    assert parts["var_composition"] == pytest.approx(parts["var_split"] - 0.02)


def test_pure_seed_noise_leaves_no_split_component():
    rng = np.random.default_rng(2)
    parts = decompose(rng.normal(0.0, 0.2, size=(300, 3)), np.zeros((300, 3)), 0.24)
    assert parts["var_split"] < 0.2 * parts["var_seed"]


def test_the_half_width_keeps_the_floor_for_splits_but_not_for_seeds():
    parts = {"var_split": 0.09, "var_seed": 0.04, "test_train_ratio": 0.24}
    seed_only = {**parts, "var_split": 0.0}
    # seeds average away: 4 seeds per split narrow a seed-only interval about twice
    assert half_width(seed_only, 8, 4) < 0.55 * half_width(seed_only, 8, 1)
    # splits do not: endless repeats keep sqrt(0.24 * var_split) times the t quantile
    floor = 1.96 * math.sqrt(0.24 * 0.09)
    assert half_width(parts, 10_000, 1) == pytest.approx(math.sqrt(floor**2 + 1.96**2 * 0.04 / 10_000), rel=1e-3)
    assert half_width(parts, 32, 1) > floor


def test_the_test_sampling_bootstrap_moves_whole_trials():
    # two trials, each with a constant difference: resampling frames would see no spread inside a
    # trial; resampling trials sees the gap between them
    trials = np.repeat(["a", "b"], 50)
    diff = np.repeat([0.0, 1.0], 50)
    var = bootstrap_difference_variance(diff, np.zeros(100), trials, n_boot=2000)
    assert var == pytest.approx(0.125, rel=0.15)      # the mean of 2 draws of {0, 1}: variance 0.25 / 2
    assert math.isnan(bootstrap_difference_variance(diff[:50], np.zeros(50), trials[:50]))   # one trial


def test_fewer_than_two_splits_or_seeds_is_refused():
    with pytest.raises(TactilepipeError, match="2 splits x 2 seeds"):
        decompose(np.zeros((3, 1)), np.zeros((3, 1)), 0.2)


def _study_noise():
    """studies/tool_models/study_noise.py, imported from its file (studies are scripts, not a package)."""
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parents[2] / "studies" / "tool_models" / "study_noise.py"
    spec = importlib.util.spec_from_file_location("study_noise", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_repeats_that_decide_are_the_fewest_whose_interval_fits_and_none_below_the_floor():
    from scipy import stats
    study = _study_noise()
    var_split, var_seed, ratio = 0.09, 0.05, 0.25

    def reach(k, power):
        z = stats.norm.ppf(power) if power > 0.5 else 0.0
        return (stats.t.ppf(0.975, k - 1) + z) * math.sqrt((1 / k + ratio) * var_split + var_seed / k)

    for need, power in ((0.40, 0.5), (0.60, 0.8)):
        k = study.repeats_to_decide(need, var_split, var_seed, ratio, power)
        assert k is not None and reach(k, power) <= need < reach(k - 1, power)
    # 80 % power adds z = 0.84 to the floor: 0.40 is within reach at even odds, never at 80 %
    assert study.repeats_to_decide(0.40, var_split, var_seed, ratio, 0.8) is None
    floor = 1.96 * math.sqrt(ratio * var_split)   # endless repeats: 0.294
    assert study.repeats_to_decide(floor * 0.99, var_split, var_seed, ratio, 0.5) is None
    assert study.repeats_to_decide(0.0, var_split, var_seed, ratio, 0.5) is None


def test_the_shared_test_sampling_is_read_from_one_model_and_an_ensemble():
    """One run's bootstrap variance is shared + own (its seed's errors on the trials); an ensemble of
    M seeds keeps own / M: the shared part is (M v_ens - v_one) / (M - 1)."""
    study = _study_noise()
    shared, own, m = 0.0003, 0.0006, 3
    assert study.shared_test_variance(shared + own, shared + own / m, m) == pytest.approx(shared)
    assert study.shared_test_variance(0.001, 0.0001, 3) == 0.0            # noisier than possible: none


def test_what_a_design_decides_keeps_the_shared_test_sampling_in_the_split_term():
    study = _study_noise()
    parts = {"var_split": 0.0, "var_seed": 0.0035, "var_test": 0.028 ** 2, "test_train_ratio": 0.25}
    built = {"mae_difference": -0.022, "margin": 0.036, "verdict": "undecided"}
    out = study.decidable(parts, built, var_test_ensemble=0.021 ** 2, seeds=3)
    shared = (3 * 0.021 ** 2 - 0.028 ** 2) / 2
    assert out["need"] == pytest.approx(0.022)              # |mean| beats margin - |mean| = 0.014
    assert out["var_test_shared"] == pytest.approx(shared)
    assert out["floor"] == pytest.approx(1.96 * math.sqrt(0.25 * shared), rel=1e-3)   # 0.016 N < 0.022 N
    # under the report's interval the seed's variance keeps the floor too: out of reach at any K
    assert out["K_report"] is None and out["K_even"] is not None and out["K_80"] is None
    # no margin (no full model): only excluding zero decides
    assert study.decidable(parts, {**built, "margin": math.nan}, 0.021 ** 2, 3)["need"] == pytest.approx(0.022)
