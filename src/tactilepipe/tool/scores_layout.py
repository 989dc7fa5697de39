"""A tool scene's scores.json as `tactilepipe diff` reads it (pipeline/diff.py): each model's scores
over the repeated splits, which draws two runs share, and the layout of earlier revisions.

Until scores.json, each model's (and baseline's) top-level ``mae``, ``rmse`` and ``r2`` (and a
variant's ``slope`` and ``intercept``) were its first split's, named by the scene's top-level
``split``, beside ``test_pairs`` (``current_layout`` reads them in today's).
"""

from __future__ import annotations

import copy
import math

from tactilepipe.core.study import same_value, score_number

SCORES = ("mae", "rmse", "r2")
FIRST_SPLIT_KEYS = ("mae", "rmse", "r2", "slope", "intercept")     # a model's scores on the first split
# stages whose change leaves the draws (splits) alone: the models and their report
MODEL_STAGES = {"tool-train", "tool-model-report"}
# compared as scored series, not as single values
SINGLE_SKIP = {"per_split", "over_splits"}


def scored_keys(node: dict) -> set[str]:
    """A model's top-level scores are the means of its scored series: compared there, not twice."""
    return set(SCORES) if "per_split" in node else set()


def scored_series(metrics: dict) -> dict[tuple[str, str], dict]:
    """``{(model, metric): {"value", "draws", "names", "low", "high"}}``: each variant's and
    baseline's scores over the repeated splits, each draw named by its split."""
    series = {}
    models = {k: v for k, v in metrics.items() if isinstance(v, dict) and "per_split" in v}
    models.update({f"baseline {k}": v for k, v in metrics.get("baselines", {}).items() if "per_split" in v})
    splits = metrics.get("splits")
    for model, m in models.items():
        for score in SCORES:
            ov = m["over_splits"][score]
            draws = [score_number(x) for x in m["per_split"][score]]
            series[(model, score)] = {"value": ov["mean"], "draws": draws,
                                      "names": list(splits) if splits and len(splits) == len(draws) else None,
                                      "low": score_number(ov["low"]), "high": score_number(ov["high"])}
    return series


def draws_shown_same(old: dict, new: dict) -> set[str]:
    """The draws (splits) two runs demonstrably share, whatever their provenance says: the
    baselines are fitted deterministically on each draw's training part and scored on its test
    part, so a draw of the same name with the same test size on which every baseline scores
    exactly the same in both runs is the same split of the same data. This pairs runs whose
    earlier stages' code changed without changing the data (a refactor)."""
    names = []
    for m in (old, new):
        splits, sizes = m.get("splits") or [], m.get("test_pairs_per_split") or []
        names.append({n: k for k, n in enumerate(splits)} if len(sizes) == len(splits) else {})
    a, b = old.get("baselines") or {}, new.get("baselines") or {}
    if not a or set(a) != set(b):
        return set()
    same = set()
    for name in set(names[0]) & set(names[1]):
        i, j = names[0][name], names[1][name]
        if old["test_pairs_per_split"][i] != new["test_pairs_per_split"][j]:
            continue
        try:
            if all(same_value(score_number(a[base]["per_split"][score][i]), score_number(b[base]["per_split"][score][j]))
                   and math.isfinite(score_number(a[base]["per_split"][score][i]))
                   for base in a for score in SCORES):
                same.add(name)
        except (KeyError, IndexError, TypeError, ValueError):
            continue
    return same


def test_train_ratio(run: dict) -> float:
    """n_test/n_train of one draw, for the corrected resampled t the reports use."""
    return float(run["metrics"].get("test_train_ratio", 0.0) or 0.0)


def current_layout(metrics: dict) -> dict:
    """The scores in today's layout: an earlier revision's first-split scores move under
    ``first_split`` and the top-level scores become the means over the splits, as the report
    writes them now. Today's layout is returned as it is."""
    if "first_split" in metrics:
        return metrics
    m = copy.deepcopy(metrics)
    if "split" in m or "test_pairs" in m:
        m["first_split"] = {"split": m.pop("split", None), "test_pairs": m.pop("test_pairs", None)}
    models = [v for v in m.values() if isinstance(v, dict) and "per_split" in v]
    models += [v for v in (m.get("baselines") or {}).values() if isinstance(v, dict) and "per_split" in v]
    for model in models:
        model["first_split"] = {"split": m.get("first_split", {}).get("split")} | \
            {k: model.pop(k) for k in FIRST_SPLIT_KEYS if k in model}
        model.update({s: model["over_splits"][s]["mean"] for s in SCORES if s in model["over_splits"]})
    return m
