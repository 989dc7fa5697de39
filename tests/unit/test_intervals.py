"""Intervals and paired differences against values computed by hand."""

import math

import pytest

from tactilepipe.core.errors import TactilepipeError
from tactilepipe.core.intervals import interval, paired_difference, ranking, ranking_text

T_975_DF2 = 4.30265273   # Student t, 97.5 % quantile, 2 and 4 degrees of freedom (tables)
T_975_DF4 = 2.77644511


def test_interval_of_three_values():
    # mean 2, sample std 1, half width t(2)·1/√3
    s = interval([1.0, 2.0, 3.0])
    assert s["mean"] == 2.0 and s["std"] == 1.0 and s["n"] == 3 and s["n_undefined"] == 0
    half = T_975_DF2 / math.sqrt(3)
    assert s["low"] == pytest.approx(2.0 - half, abs=1e-8) and s["high"] == pytest.approx(2.0 + half, abs=1e-8)
    assert s["low"] == pytest.approx(-0.484137711843753, abs=1e-8)


def test_corrected_interval_widens_by_the_test_train_ratio():
    # 5 draws, each testing on 1/4 of what it trains on: variance of the mean s²·(1/5 + 1/4)
    s = interval([1, 2, 3, 4, 5], test_train_ratio=0.25)
    half = T_975_DF4 * math.sqrt(2.5) * math.sqrt(0.2 + 0.25)
    assert s["low"] == pytest.approx(3 - half, abs=1e-8) and s["high"] == pytest.approx(3 + half, abs=1e-8)
    assert s["low"] == pytest.approx(0.055135257783658, abs=1e-8)
    plain = interval([1, 2, 3, 4, 5])
    assert plain["high"] - plain["low"] < s["high"] - s["low"]


def test_undefined_draws_are_left_out_and_counted():
    s = interval([1.0, float("nan"), 3.0])
    assert s["n"] == 2 and s["n_undefined"] == 1 and s["mean"] == 2.0
    one = interval([0.7])
    assert one["mean"] == 0.7 and math.isnan(one["std"]) and math.isnan(one["low"]) and math.isnan(one["high"])


def test_paired_difference_that_cannot_separate():
    d = paired_difference([0.9, 0.8, 0.85], [0.7, 0.75, 0.72])
    assert d["per_draw"] == pytest.approx([0.2, 0.05, 0.13])
    assert d["mean"] == pytest.approx(0.38 / 3)
    assert d["std"] == pytest.approx(math.sqrt(0.0112666666666 / 2), rel=1e-9)
    assert d["low"] == pytest.approx(-0.05978161826227, abs=1e-9)
    assert d["excludes_zero"] is False


def test_paired_difference_separates_what_the_unpaired_intervals_cannot():
    # both methods swing together from draw to draw; the second is always 0.02 lower
    a = [0.90, 0.70, 0.80, 0.95, 0.60]
    b = [x - 0.02 for x in a]
    ia, ib = interval(a), interval(b)
    assert ia["low"] < ib["high"]                       # unpaired intervals overlap widely
    d = paired_difference(a, b)
    assert d["excludes_zero"] is True and d["low"] == pytest.approx(0.02, abs=1e-8)


def test_paired_difference_refuses_unpaired_draws():
    with pytest.raises(TactilepipeError, match="3 draws against 2"):
        paired_difference([1, 2, 3], [1, 2])
    with pytest.raises(TactilepipeError, match="level"):
        interval([1, 2], level=95)


def test_ranking_marks_which_neighbours_the_intervals_cannot_order():
    per_draw = {"b": [0.80, 0.70, 0.75], "a": [0.90, 0.80, 0.85], "c": [0.79, 0.71, 0.74]}
    rows = ranking(per_draw, higher_is_better=True)
    assert [r["method"] for r in rows] == ["a", "b", "c"]
    assert rows[0]["separated_from_next"] is True         # a - b = 0.1 on every draw
    assert rows[1]["separated_from_next"] is False        # b - c = 0.01, -0.01, 0.01
    assert ranking_text(rows) == "a > b ≈ c"
    errors = ranking({"x": [1.0, 1.2, 1.1], "y": [2.0, 2.1, 2.2]}, higher_is_better=False)
    assert [r["method"] for r in errors] == ["x", "y"] and errors[0]["separated_from_next"]
