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
