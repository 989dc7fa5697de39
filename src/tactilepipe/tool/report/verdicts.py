"""What the repeated splits of a tool scene say: intervals, paired differences and verdicts.

Scores come per draw (repeat k of the default split: its own trials and model seed) as
``{model: {metric: [value per draw]}}``. Every comparison is paired: two models are compared draw
by draw on the same test trials, so the spread between splits, which they share, cancels.
A model "beats" another only when the interval of its improvement excludes zero on both MAE and R²:
one metric alone, or a better mean the draws cannot separate from chance, is not a verdict.

An ordering "a < b (MAE)" is judged four ways on the interval of the paired MAE difference b - a
and the equivalence margin m (params.yaml ``tool_report.equivalence_margin``, a fraction of the
full model's mean MAE fixed before the build):

- **equivalent**: the interval lies inside (-m, m), the two one-sided tests (TOST) at the tails the
  95 % interval leaves (2.5 % each) on the same corrected t. This wins over an ordering when the
  interval also excludes zero: the sign is then resolved but the difference is smaller than the
  smallest one that matters, and "a is better" would claim more than the data show. Such a row
  keeps ``excludes_zero`` true, so the resolved sign is not lost.
- **holds** / **reversed**: otherwise, the interval lies above / below zero.
- **undecided**: neither; its ``power`` line says how many repeats would decide it.
"""

from __future__ import annotations

import math

from tactilepipe.core.intervals import (LEVEL, equivalence_p, half_width, interval, paired_difference, ranking,
                                         ranking_text, repeats_for_half_width)

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
ORDERING_FIELDS = ["claim", "better", "worse", "mae_difference", "low", "high", "excludes_zero", "margin",
                   "equivalence_p", "verdict", "repeats_to_order", "repeats_to_equivalence", "power"]
VERDICTS = ("holds", "reversed", "equivalent", "undecided")


def margin_n(scores: dict[str, dict[str, list[float]]], fraction: float) -> float:
    """The equivalence margin in N: ``fraction`` of the full model's mean MAE over the draws (NaN
    without a full model: then no ordering is judged equivalent)."""
    if "full" not in scores:
        return math.nan
    return fraction * interval(scores["full"]["mae"])["mean"]


def verdict_of(low: float, high: float, margin: float) -> str:
    """The four-way verdict of an interval of worse - better against the margin (see the module)."""
    if not (math.isfinite(low) and math.isfinite(high)):
        return "undecided"
    if math.isfinite(margin) and -margin < low and high < margin:
        return "equivalent"
    return "holds" if low > 0 else "reversed" if high < 0 else "undecided"


def power_line(d: dict, margin: float, test_train_ratio: float) -> dict:
    """For an undecided difference ``d`` (a ``paired_difference``), the repeats K that would decide
    it were its mean and spread s to stay as observed, with r = n_test/n_train held:

        h(K) = t(0.975, K - 1) · s · sqrt(1/K + r)       (half-width of the 95 % interval)

    - to exclude zero at the observed mean: the fewest K with h(K) < |mean|;
    - to show equivalence at the observed mean: the fewest K with h(K) < margin - |mean|.

    Each is None when no K can: h(K) never goes below its floor h(inf) = 1.96 · s · sqrt(r), the
    part of the variance due to testing on n_test trials that more repeats do not shrink (or, for
    equivalence, when the observed mean lies outside the margin). Decided differences get None and
    an empty line.
    """
    mean, std, level = d["mean"], d["std"], d.get("level", LEVEL)
    if verdict_of(d["low"], d["high"], margin) != "undecided":
        return {"repeats_to_order": None, "repeats_to_equivalence": None, "power": ""}
    if d["n"] < 2 or not math.isfinite(std):
        return {"repeats_to_order": None, "repeats_to_equivalence": None,
                "power": "no spread to extrapolate: fewer than two draws"}
    to_order = repeats_for_half_width(std, abs(mean), level, test_train_ratio)
    room = margin - abs(mean) if math.isfinite(margin) else math.nan
    to_equivalence = repeats_for_half_width(std, room, level, test_train_ratio) if room > 0 else None
    floor = half_width(std, math.inf, level, test_train_ratio)
    parts = [f"K = {to_order} would exclude 0 at the observed mean" if to_order else
             f"no K excludes 0: the floor ±{floor:.3g} N (n_test/n_train = {test_train_ratio:.3g}) "
             f"exceeds the mean difference {abs(mean):.3g} N"]
    if not math.isfinite(margin):
        parts.append("equivalence not judged: no full model to set the margin")
    elif to_equivalence:
        parts.append(f"K = {to_equivalence} would show equivalence within ±{margin:.3g} N")
    elif room <= 0:
        parts.append(f"no K shows equivalence: the mean difference {abs(mean):.3g} N is outside the margin ±{margin:.3g} N")
    else:
        parts.append(f"no K shows equivalence: the floor ±{floor:.3g} N exceeds the room {room:.3g} N "
                     "between the mean difference and the margin")
    return {"repeats_to_order": to_order, "repeats_to_equivalence": to_equivalence, "power": "; ".join(parts)}


def judge(better: str, worse: str, scores: dict[str, dict[str, list[float]]], margin: float,
          test_train_ratio: float) -> dict:
    """"better < worse (MAE)" judged on the paired MAE difference worse - better over the draws."""
    d = paired_difference(scores[worse]["mae"], scores[better]["mae"], test_train_ratio=test_train_ratio)
    return {"claim": f"{better} < {worse} (MAE)", "better": better, "worse": worse, "mae_difference": d["mean"],
            "low": d["low"], "high": d["high"], "excludes_zero": d["excludes_zero"],
            "margin": margin, "equivalence_p": equivalence_p(d["mean"], d["std"], d["n"], margin, test_train_ratio),
            "verdict": verdict_of(d["low"], d["high"], margin)} | power_line(d, margin, test_train_ratio)


def paper_orderings(scene: str, scores: dict[str, dict[str, list[float]]], test_train_ratio: float,
                    margin: float = math.nan) -> list[dict]:
    """Each of the study's orderings for this scene that both models of are in ``scores``, judged."""
    return [judge(better, worse, scores, margin, test_train_ratio) for better, worse in PAPER_ORDERINGS[scene]
            if better in scores and worse in scores]
