"""The four-way verdict of an ordering (holds, reversed, equivalent, undecided) against its interval and
the equivalence margin, the TOST behind "equivalent", and the power line of an undecided one."""

from __future__ import annotations

import math

import pytest
from scipy import stats

from tactilepipe.core.intervals import equivalence_p, half_width, repeats_for_half_width
from tactilepipe.tool.report.verdicts import judge, margin_n, paper_orderings, verdict_of

RATIO = 0.25                      # n_test/n_train of each draw
FULL = [1.0, 1.0, 1.0, 1.0]       # the full model's MAE on 4 draws: margin 0.1 N at fraction 0.1


def _judged(differences: list[float]) -> dict:
    """"full < other (MAE)" where other's MAE is full's plus ``differences`` draw by draw."""
    scores = {"full": {"mae": FULL}, "other": {"mae": [f + d for f, d in zip(FULL, differences)]}}
    return judge("full", "other", scores, margin_n(scores, 0.1), RATIO)


def _expected(row: dict) -> str:
    """The verdict read off the stored interval and margin, as the report's docs define it."""
    low, high, m = row["low"], row["high"], row["margin"]
    return "equivalent" if -m < low and high < m else "holds" if low > 0 else "reversed" if high < 0 else "undecided"


def _h(std: float, k: int) -> float:
    """Half-width of the corrected 95 % interval on k draws, written out independently."""
    return stats.t.ppf(0.975, k - 1) * std * math.sqrt(1 / k + RATIO)


CASES = {   # per-draw MAE differences (other - full) -> verdict
    "holds": ([0.5, 0.6, 0.5, 0.6], "holds"),
    "reversed": ([-0.5, -0.6, -0.5, -0.6], "reversed"),
    "equivalent straddling zero": ([0.01, -0.01, 0.01, -0.01], "equivalent"),
    # resolved sign (interval about [0.022, 0.048]) but inside ±0.1: equivalence wins
    "equivalent with a resolved sign": ([0.03, 0.04, 0.03, 0.04], "equivalent"),
    "undecided, more repeats order it": ([0.0, 0.4, 0.1, 0.3], "undecided"),
    "undecided, more repeats show equivalence": ([0.02, -0.02, 0.06, -0.06], "undecided"),
    "undecided, no K at this data size": ([-0.3, 0.3, -0.25, 0.27], "undecided"),
}


@pytest.mark.parametrize("case", CASES)
def test_each_verdict_follows_its_interval_and_margin(case):
    differences, verdict = CASES[case]
    row = _judged(differences)
    assert row["margin"] == pytest.approx(0.1)
    assert row["verdict"] == verdict == _expected(row), (case, row)
    # the TOST on the same corrected t agrees with "interval inside the margin" (each test at 2.5 %)
    assert (row["equivalence_p"] < 0.025) == (verdict == "equivalent"), row
    assert row["excludes_zero"] == (row["low"] > 0 or row["high"] < 0)
    if verdict != "undecided":
        assert (row["power"], row["repeats_to_order"], row["repeats_to_equivalence"]) == ("", None, None)


def test_a_resolved_but_negligible_difference_is_equivalent_and_keeps_its_sign():
    row = _judged(CASES["equivalent with a resolved sign"][0])
    assert 0 < row["low"] < row["high"] < 0.1 and row["excludes_zero"] is True and row["verdict"] == "equivalent"
    # the same interval with a margin it does not fit in is an ordering that holds
    assert verdict_of(row["low"], row["high"], 0.04) == "holds"
    # no full model, no margin: the ordering verdicts only
    assert verdict_of(row["low"], row["high"], math.nan) == "holds"


def test_power_line_names_the_repeats_that_would_exclude_zero():
    row = _judged(CASES["undecided, more repeats order it"][0])
    std, mean = stats.tstd([0.0, 0.4, 0.1, 0.3]), 0.2
    k = row["repeats_to_order"]
    assert k is not None and _h(std, k) < mean <= _h(std, k - 1), (k, row)
    assert k > 4 and f"K = {k} would exclude 0" in row["power"]
    # the observed mean (0.2 N) lies outside the margin: no K can show equivalence
    assert row["repeats_to_equivalence"] is None and "outside the margin" in row["power"]


def test_power_line_names_the_repeats_that_would_show_equivalence():
    row = _judged(CASES["undecided, more repeats show equivalence"][0])
    std = stats.tstd([0.02, -0.02, 0.06, -0.06])
    k = row["repeats_to_equivalence"]
    assert k is not None and _h(std, k) < 0.1 - abs(row["mae_difference"]) <= _h(std, k - 1), (k, row)
    assert f"K = {k} would show equivalence" in row["power"]
    assert row["repeats_to_order"] is None and "no K excludes 0" in row["power"]    # mean 0: nothing to order


def test_power_line_says_when_the_floor_term_alone_keeps_it_undecided():
    row = _judged(CASES["undecided, no K at this data size"][0])
    std = stats.tstd([-0.3, 0.3, -0.25, 0.27])
    floor = 1.959964 * std * math.sqrt(RATIO)
    assert floor > 0.1 > abs(row["mae_difference"])          # wider than the margin itself, at any K
    assert (row["repeats_to_order"], row["repeats_to_equivalence"]) == (None, None)
    assert "no K excludes 0: the floor" in row["power"] and "no K shows equivalence: the floor" in row["power"]
    assert half_width(std, math.inf, test_train_ratio=RATIO) == pytest.approx(floor, rel=1e-6)
    # without the n_test/n_train term the same spread is decided by enough repeats
    assert repeats_for_half_width(std, 0.1, test_train_ratio=0.0) is not None
    assert repeats_for_half_width(std, 0.1, test_train_ratio=RATIO) is None


def test_tost_p_values_by_hand():
    # mean 0.02, s 0.1, 5 draws, r 0.25: se = 0.1·sqrt(0.45); margin 0.2
    se = 0.1 * math.sqrt(0.45)
    expected = max(stats.t.sf((0.02 + 0.2) / se, 4), stats.t.cdf((0.02 - 0.2) / se, 4))
    assert equivalence_p(0.02, 0.1, 5, 0.2, 0.25) == pytest.approx(expected, rel=1e-12)
    assert math.isnan(equivalence_p(0.02, 0.1, 1, 0.2, 0.25)) and math.isnan(equivalence_p(0.02, 0.1, 5, math.nan))


def test_orderings_without_a_full_model_are_never_equivalent():
    scores = {"no_gam": {"mae": [1.0, 1.01, 1.0]}, "no_ref": {"mae": [1.0, 1.0, 1.01]}}
    (row,) = paper_orderings("tool_normal", scores, 0.0, margin_n(scores, 0.1))
    assert math.isnan(row["margin"]) and row["verdict"] == "undecided"
    assert "equivalence not judged" in row["power"]


def test_a_margin_wider_than_a_tenth_of_the_full_models_mae_is_refused():
    from tactilepipe.core.config import load_params
    from tactilepipe.core.errors import ConfigError
    assert load_params()["tool_report"]["equivalence_margin"] == 0.1
    with pytest.raises(ConfigError, match=r"at 'tool_report.equivalence_margin': 0.2 is greater than the maximum of 0.1"):
        load_params(overrides={"tool_report": {"equivalence_margin": 0.2}})



def test_the_power_line_is_safe_in_a_markdown_table_cell():
    """The power line is a cell of paper_orderings.md: a '|' in it would split the row."""
    from tactilepipe.core.intervals import paired_difference
    from tactilepipe.tool.report.verdicts import power_line
    undecided = [[0.05, -0.3, 0.4, -0.2, 0.3, -0.35, 0.1, 0.2],        # the floor leaves no room
                 [0.9, -0.3, 1.1, -0.2, 0.8, -0.1, 0.7, 0.0]]          # the mean is outside the margin
    lines = [power_line(paired_difference(b, [0.0] * 8, test_train_ratio=0.25), 0.1, 0.25)["power"] for b in undecided]
    assert "the floor" in lines[0] and "outside the margin" in lines[1], lines
    assert all("|" not in line for line in lines), lines
