"""Regression metrics computed on the full set of predictions (never averaged per batch).

R² is undefined when the true values do not vary (a single class, a constant label): it is then
reported as NaN with a reason (``r2_detail``), never as a number and never as an exception.
Constant means constant up to floating-point resolution: labels such as [0.1, 0.1, 0.1] have a
mean that differs from 0.1 in the last bit, and dividing by that round-off "variance" would give
an R² of -1e30 instead of "undefined".
"""

from __future__ import annotations

import math

import numpy as np

from tactilepipe.core.errors import ArgumentError

R2_CONSTANT = "undefined: the true values are constant (no variance to explain)"
R2_EMPTY = "undefined: no samples"
R2_NONFINITE = "undefined: NaN or inf among the true values or the predictions"
UNDEFINED = "undefined"


def _ss_tot_is_zero(y_true: np.ndarray, ss_tot: float) -> bool:
    """True when the spread of y_true is zero or at the level of its float round-off."""
    scale = float(np.max(np.abs(y_true))) if len(y_true) else 0.0
    resolution = 16 * np.finfo(np.float64).eps * scale
    return ss_tot <= len(y_true) * resolution**2


def r2_detail(y_true, y_pred) -> tuple[float, str | None]:
    """(R², None) when defined, else (NaN, reason)."""
    y_true = np.asarray(y_true, np.float64).reshape(-1)
    y_pred = np.asarray(y_pred, np.float64).reshape(-1)
    if len(y_true) != len(y_pred):
        raise ArgumentError(f"r2: {len(y_true)} true values (y_true) but {len(y_pred)} predictions (y_pred)")
    if len(y_true) == 0:
        return float("nan"), R2_EMPTY
    if not np.isfinite(y_true).all():
        return float("nan"), R2_NONFINITE
    # R² is scale-free: work in units of max |y_true| so that squares of labels near 1e-300 or
    # 1e+300 neither underflow to 0 nor overflow to inf
    scale = float(np.abs(y_true).max()) or 1.0
    y_true = y_true / scale
    ss_tot = float(((y_true - y_true.mean()) ** 2).sum())
    if _ss_tot_is_zero(y_true, ss_tot):
        return float("nan"), R2_CONSTANT
    if not np.isfinite(y_pred).all():
        return float("nan"), R2_NONFINITE
    with np.errstate(over="ignore"):
        ss_res = float(((y_true - y_pred / scale) ** 2).sum())
    return 1.0 - ss_res / ss_tot, None


def r2_score(y_true, y_pred) -> float:
    """Coefficient of determination; NaN (not an exception) when it is undefined (``r2_detail``
    gives the reason): constant targets, no samples, or non-finite values."""
    return r2_detail(y_true, y_pred)[0]


def is_defined(value) -> bool:
    return value is not None and isinstance(value, (int, float, np.floating, np.integer)) and math.isfinite(value)


def format_metric(value, fmt: str = "{:.4f}") -> str:
    """A metric for a report: the number, or "undefined" (NaN / None)."""
    return fmt.format(value) if is_defined(value) else UNDEFINED


def mae(y_true, y_pred) -> float:
    return float(np.mean(np.abs(np.asarray(y_true, np.float64) - np.asarray(y_pred, np.float64))))


def rmse(y_true, y_pred) -> float:
    return float(np.sqrt(np.mean((np.asarray(y_true, np.float64) - np.asarray(y_pred, np.float64)) ** 2)))
