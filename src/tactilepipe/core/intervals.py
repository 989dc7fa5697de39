"""Intervals over repeated train/test draws, and paired differences between methods.

A score measured on K draws (folds, splits) is reported as mean, sample std and a 95 % interval of
the mean from Student's t with K - 1 degrees of freedom. The draws share training data, so they are
not independent and the plain t-interval is too narrow. With ``test_train_ratio`` (n_test/n_train
of one draw) the variance of the mean is widened from s²/K to s²·(1/K + n_test/n_train), the
corrected resampled t of Nadeau and Bengio ("Inference for the Generalization Error", Machine
Learning 52, 2003), which is what the tables report.

Two methods compared on the same draws are compared by their per-draw difference (paired), which
removes the draw-to-draw spread they share: the interval of the mean difference says whether the
data can tell them apart.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from tactilepipe.core.errors import TactilepipeError

LEVEL = 0.95


def interval(values, level: float = LEVEL, test_train_ratio: float = 0.0) -> dict:
    """Mean, sample std (ddof 1), n and the two-sided ``level`` interval of the mean of ``values``.

    NaN values (an undefined score on a draw) are left out and counted in ``n_undefined``. With
    fewer than two defined values the interval is NaN: one draw says nothing about the spread.
    """
    if not 0.0 < level < 1.0:
        raise TactilepipeError(f"interval: level must be in (0, 1), got {level}")
    if test_train_ratio < 0.0:
        raise TactilepipeError(f"interval: test_train_ratio must be >= 0, got {test_train_ratio}")
    v = np.asarray(values, np.float64).reshape(-1)
    ok = np.isfinite(v)
    v = v[ok]
    n = len(v)
    mean = float(v.mean()) if n else math.nan
    std = float(v.std(ddof=1)) if n >= 2 else math.nan
    if n >= 2:
        half = float(stats.t.ppf(0.5 + level / 2, n - 1)) * std * math.sqrt(1.0 / n + test_train_ratio)
        low, high = mean - half, mean + half
    else:
        low = high = math.nan
    return {"mean": mean, "std": std, "n": n, "n_undefined": int((~ok).sum()), "low": low, "high": high,
            "level": level}


def paired_difference(a, b, level: float = LEVEL, test_train_ratio: float = 0.0) -> dict:
    """``interval`` of a - b draw by draw, plus the per-draw differences and whether the interval
    excludes zero (the data separate the two). Draws where either score is undefined are left out."""
    a = np.asarray(a, np.float64).reshape(-1)
    b = np.asarray(b, np.float64).reshape(-1)
    if a.shape != b.shape:
        raise TactilepipeError(f"paired_difference: {len(a)} draws against {len(b)}; pair the same draws")
    d = a - b
    out = interval(d, level, test_train_ratio)
    out["per_draw"] = [float(x) for x in d]
    out["excludes_zero"] = bool(np.isfinite(out["low"]) and (out["low"] > 0.0 or out["high"] < 0.0))
    return out


def ranking(per_draw: dict[str, list[float]], higher_is_better: bool, level: float = LEVEL,
            test_train_ratio: float = 0.0) -> list[dict]:
    """Methods sorted by mean score, best first, each with whether the paired interval against the
    next one down excludes zero. ``separated_from_next`` False means the data cannot order the two."""
    means = {m: interval(v, level, test_train_ratio)["mean"] for m, v in per_draw.items()}
    order = sorted(means, key=lambda m: (-means[m] if higher_is_better else means[m]))
    out = []
    for i, m in enumerate(order):
        row = {"method": m, "mean": means[m]}
        if i + 1 < len(order):
            nxt = order[i + 1]
            d = paired_difference(per_draw[m], per_draw[nxt], level, test_train_ratio)
            row.update({"next": nxt, "difference": d["mean"], "low": d["low"], "high": d["high"],
                        "separated_from_next": d["excludes_zero"]})
        out.append(row)
    return out


def ranking_text(rows: list[dict]) -> str:
    """"a > b ≈ c > d", best first: '>' reads "better than, and the interval separates them", '≈'
    "the interval cannot order them"."""
    parts = []
    for row in rows:
        parts.append(row["method"])
        if "next" in row:
            parts.append(">" if row["separated_from_next"] else "≈")
    return " ".join(parts)


def _standard_error(std: float, n: int, test_train_ratio: float) -> float:
    return std * math.sqrt(1.0 / n + test_train_ratio)


def equivalence_p(mean: float, std: float, n: int, margin: float, test_train_ratio: float = 0.0) -> float:
    """Two one-sided tests (TOST) that a mean difference lies inside (-margin, margin), on the corrected
    resampled t of ``interval`` (standard error s·sqrt(1/n + n_test/n_train), n - 1 degrees of freedom).

    Returns the larger of the two one-sided p-values, of H0 "difference <= -margin" (t = (mean +
    margin)/se) and of H0 "difference >= margin" (t = (mean - margin)/se). Equivalence is shown at
    ``level`` when it is below (1 - level)/2: each one-sided test at the tail the two-sided
    ``level`` interval leaves on its side, which is exactly "the interval lies inside the margin".
    NaN without two draws or a finite positive margin.
    """
    if n < 2 or not (math.isfinite(std) and math.isfinite(margin) and margin > 0):
        return math.nan
    se = _standard_error(std, n, test_train_ratio)
    if se == 0.0:
        return 0.0 if abs(mean) < margin else 1.0
    below = float(stats.t.sf((mean + margin) / se, n - 1))
    above = float(stats.t.cdf((mean - margin) / se, n - 1))
    return max(below, above)


def half_width(std: float, k: float, level: float = LEVEL, test_train_ratio: float = 0.0) -> float:
    """The half-width of ``interval`` on k draws of spread ``std``: t(level, k - 1)·s·sqrt(1/k + r);
    k = inf gives the floor z(level)·s·sqrt(r) that no number of draws goes below."""
    if math.isinf(k):
        return float(stats.norm.ppf(0.5 + level / 2)) * std * math.sqrt(test_train_ratio)
    return float(stats.t.ppf(0.5 + level / 2, k - 1)) * _standard_error(std, int(k), test_train_ratio)


def repeats_for_half_width(std: float, target: float, level: float = LEVEL, test_train_ratio: float = 0.0,
                           most: int = 10**9) -> int | None:
    """The fewest draws K >= 2 whose interval half-width is below ``target``, if the spread stays ``std``.

    With r = n_test/n_train held (the same split fractions), the half-width
        h(K) = t(level, K - 1) · s · sqrt(1/K + r)
    falls with K towards the floor h(inf) = z(level) · s · sqrt(r): 1/K is the part more draws
    remove, r the part they cannot (every draw tests on as few trials as before). So when
    ``target`` <= h(inf) no K reaches it at this data size and the answer is None; otherwise the
    smallest K with h(K) < target (h falls monotonically: bisection). None also past ``most``.
    """
    if not (math.isfinite(std) and math.isfinite(target)) or target <= 0:
        return None
    if target <= half_width(std, math.inf, level, test_train_ratio):
        return None
    low, high = 1, 2                                 # h(low) >= target (h(1) is infinite), h(high)?
    while half_width(std, high, level, test_train_ratio) >= target:
        if high >= most:
            return None
        low, high = high, min(2 * high, most)
    while high - low > 1:
        mid = (low + high) // 2
        if half_width(std, mid, level, test_train_ratio) >= target:
            low = mid
        else:
            high = mid
    return high
