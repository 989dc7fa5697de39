"""What the repeated splits of a tool scene say: intervals, paired differences and verdicts.

Scores come per draw (repeat k of the default split: its own trials and model seed) as
``{model: {metric: [value per draw]}}``. Every comparison is paired: two models are compared draw
by draw on the same test trials, so the spread between splits, which they share, cancels.
A model "beats" another only when the interval of its improvement excludes zero on both MAE and R²:
one metric alone, or a better mean the draws cannot separate from chance, is not a verdict.
"""

from __future__ import annotations

from tactilepipe.core.intervals import interval, paired_difference, ranking, ranking_text

METRICS = ("mae", "rmse", "r2")

# The orderings study 000 reports for its ablations ("Grasp Independent Indirect Tool Force
# Estimation using Vision-based Tactile Sensors", Li and Thuruthel), as (better, worse) pairs. Normal
# force: the full model is best; dropping the reference frame costs more than dropping attention;
# one sensor is worst. Shear force: the full model is best on every metric.
PAPER_ORDERINGS = {
    "tool_normal": [("full", "no_gam"), ("full", "no_ref"), ("full", "single"), ("no_gam", "no_ref"),
                    ("no_ref", "single")],
    "tool_shear": [("full", "no_gam"), ("full", "no_ref"), ("full", "single")],
}


def over_draws(scores: dict[str, list[float]], test_train_ratio: float) -> dict[str, dict]:
    """Per metric: mean, std and the 95 % interval over the draws."""
    return {m: interval(scores[m], test_train_ratio=test_train_ratio) for m in METRICS}


def minus(a: dict[str, list[float]], b: dict[str, list[float]], test_train_ratio: float) -> dict[str, dict]:
    """Per metric: the paired difference a - b over the draws, with its interval."""
    return {m: paired_difference(a[m], b[m], test_train_ratio=test_train_ratio) for m in METRICS}


def versus(model: dict[str, list[float]], other: dict[str, list[float]], test_train_ratio: float) -> dict:
    """How much ``model`` improves on ``other``: MAE other - model and R² model - other (positive is
    better), each with its interval; ``beats`` when both intervals lie above zero."""
    mae = paired_difference(other["mae"], model["mae"], test_train_ratio=test_train_ratio)
    r2 = paired_difference(model["r2"], other["r2"], test_train_ratio=test_train_ratio)
    return {"mae_improvement": mae, "r2_improvement": r2,
            "beats": bool(mae["excludes_zero"] and mae["mean"] > 0 and r2["excludes_zero"] and r2["mean"] > 0)}


def order_by_mae(scores: dict[str, dict[str, list[float]]], test_train_ratio: float) -> tuple[list[dict], str]:
    """Models best first by mean MAE, each with whether the paired interval separates it from the
    next; and the same as text ("a > b ≈ c")."""
    rows = ranking({name: s["mae"] for name, s in scores.items()}, higher_is_better=False,
                   test_train_ratio=test_train_ratio)
    return rows, ranking_text(rows)


# the fields of each judged ordering, in table order (a table of no orderings still has them)
ORDERING_FIELDS = ["claim", "better", "worse", "mae_difference", "low", "high", "verdict"]


def paper_orderings(scene: str, scores: dict[str, dict[str, list[float]]], test_train_ratio: float) -> list[dict]:
    """Each of the study's orderings for this scene, judged on MAE over the draws: "holds" when the
    paired interval of worse - better lies above zero, "reversed" when below, else "undecided"."""
    out = []
    for better, worse in PAPER_ORDERINGS[scene]:
        if better not in scores or worse not in scores:
            continue
        d = paired_difference(scores[worse]["mae"], scores[better]["mae"], test_train_ratio=test_train_ratio)
        verdict = "undecided" if not d["excludes_zero"] else "holds" if d["mean"] > 0 else "reversed"
        out.append({"claim": f"{better} < {worse} (MAE)", "better": better, "worse": worse,
                    "mae_difference": d["mean"], "low": d["low"], "high": d["high"], "verdict": verdict})
    return out
