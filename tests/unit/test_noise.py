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
