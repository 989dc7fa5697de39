"""The volume scene's scores.json as `tactilepipe diff` reads it (pipeline/diff.py): each input's
R² over the folds; every other number is a single value."""

from __future__ import annotations

import math

from tactilepipe.core.study import score_number

# stages whose change leaves the draws (folds) alone: the models and their report
MODEL_STAGES = {"volume-train", "volume-gridsearch", "volume-baseline", "volume-report"}
# compared as scored series (r2: each input's mean, the series' value), not as single values
SINGLE_SKIP = {"per_split", "over_splits", "r2_folds", "r2_ci95", "r2"}


def scored_keys(node: dict) -> set[str]:
    return set()


def scored_series(metrics: dict) -> dict[tuple[str, str], dict]:
    """``{(input, "r2"): {"value", "draws", "names", "low", "high"}}``: each input's R² over the folds."""
    series = {}
    for model, draws in metrics.get("r2_folds", {}).items():
        low, high = metrics.get("r2_ci95", {}).get(model, (math.nan, math.nan))
        series[(model, "r2")] = {"value": metrics["r2"][model]["mean"], "draws": [score_number(x) for x in draws],
                                 "names": None, "low": score_number(low), "high": score_number(high)}
    return series


def draws_shown_same(old: dict, new: dict) -> set[str]:
    return set()


def test_train_ratio(run: dict) -> float:
    """n_test/n_train of one fold, from the report's folds parameters."""
    folds = (run["provenance"] or {}).get("stages", {}).get("volume-report", {}).get("params", {}).get("folds")
    return folds["test_lifts_per_volume"] / folds["train_lifts_per_volume"] if folds else 0.0


def current_layout(metrics: dict) -> dict:
    return metrics
