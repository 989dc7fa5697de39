"""Evaluation of tool-force predictions on the full set of test predictions (never per batch).

Overall MAE, RMSE, R², regression slope/intercept; |error| per tool (mean ± std, n) and per
force window (0–3, 3–6, …, >21 N, with counts); and baselines on the same split, each with the
information of the variant it is compared with (each variant's ``baseline`` in params.yaml
``tool_variants``):
- ``mean_predictor``: the training mean (everyone's baseline);
- ``tactile_rmse_linear``: least squares on each finger's RMSE against its trial's reference frame
  (``full``, ``no_gam``: both fingers and their references);
- ``rest_frame_rmse_linear``: the same against the mean reference frame of the training trials, so
  no per-trial reference (``no_ref``);
- ``one_finger_rmse_linear``: the left finger's RMSE against its reference only (``single``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tactilepipe.core.metrics import mae, r2_score, rmse
from tactilepipe.core.tool_vocabulary import BASELINES

WINDOW_EDGES = [0, 3, 6, 9, 12, 15, 18, 21]


def window_label(lo: float, hi: float | None) -> str:
    return f">{lo:g} N" if hi is None else f"{lo:g}–{hi:g} N"


def force_windows(true: np.ndarray) -> pd.Series:
    edges = WINDOW_EDGES + [np.inf]
    labels = [window_label(lo, None if np.isinf(hi) else hi) for lo, hi in zip(edges[:-1], edges[1:])]
    return pd.cut(np.clip(true, 0, None), edges, labels=labels, right=False, include_lowest=True)


def summarise(true: np.ndarray, pred: np.ndarray) -> dict:
    true, pred = np.asarray(true, float), np.asarray(pred, float)
    slope, intercept = (np.polyfit(true, pred, 1) if len(true) > 1 and np.ptp(true) > 0 else (np.nan, np.nan))
    return {"n": int(len(true)), "mae": mae(true, pred), "rmse": rmse(true, pred), "r2": r2_score(true, pred),
            "slope": float(slope), "intercept": float(intercept)}


def per_group(frame: pd.DataFrame, by: str) -> pd.DataFrame:
    err = (frame["pred"] - frame["true"]).abs()
    out = err.groupby(frame[by], observed=False).agg(["mean", "std", "count"]).reset_index()
    return out.rename(columns={"mean": "mae", "std": "std_abs_error", "count": "n"})


def evaluate(pred: pd.DataFrame) -> dict:
    """pred: columns true, pred, tool. Returns overall metrics plus per-tool and per-window tables."""
    frame = pred.assign(window=force_windows(pred["true"].to_numpy()))
    return {**summarise(frame["true"], frame["pred"]),
            "per_tool": per_group(frame, "tool").to_dict("records"),
            "per_window": per_group(frame, "window").to_dict("records")}


def tactile_rmse_features(frames: np.ndarray, references: np.ndarray, trial_index: np.ndarray,
                          chunk: int = 4096) -> np.ndarray:
    """(n, 2) RMSE (grey levels) of each finger's frame against its trial's reference."""
    out = np.empty((len(frames), 2), np.float32)
    for start in range(0, len(frames), chunk):
        cur = frames[start:start + chunk].astype(np.float32)
        ref = references[trial_index[start:start + chunk]].astype(np.float32)
        out[start:start + chunk] = np.sqrt(((cur - ref) ** 2).mean(axis=(2, 3)))
    return out


def rest_frame_rmse_features(frames: np.ndarray, references: np.ndarray, trial_index: np.ndarray,
                             train: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """(n, 2) RMSE (grey levels) of each finger's frame against the mean reference frame of the
    training trials: the tactile signal a model without a per-trial reference can see."""
    rest = references[np.unique(trial_index[np.asarray(train)])].astype(np.float32).mean(axis=0)
    out = np.empty((len(frames), 2), np.float32)
    for start in range(0, len(frames), chunk):
        cur = frames[start:start + chunk].astype(np.float32)
        out[start:start + chunk] = np.sqrt(((cur - rest) ** 2).mean(axis=(2, 3)))
    return out


def linear_fit_predictions(labels: np.ndarray, features: np.ndarray, split: dict) -> np.ndarray:
    """Test predictions of least squares (with intercept) fitted on the training rows."""
    train, test = np.asarray(split["train"]), np.asarray(split["test"])
    design = lambda idx: np.column_stack([features[idx], np.ones(len(idx))])
    coef, *_ = np.linalg.lstsq(design(train), labels[train], rcond=None)
    return design(test) @ coef


def baselines(labels: np.ndarray, rmse_features: np.ndarray, rest_features: np.ndarray,
              split: dict) -> dict[str, np.ndarray]:
    """Test predictions of every baseline (``BASELINES``) on one split. ``rmse_features``: (n, 2)
    from ``tactile_rmse_features`` (finger 0 is the left one, the ``single`` variant's); ``rest_features``:
    (n, 2) from ``rest_frame_rmse_features`` on this split's training rows."""
    train, test = np.asarray(split["train"]), np.asarray(split["test"])
    return {"mean_predictor": np.full(len(test), labels[train].mean()),
            "tactile_rmse_linear": linear_fit_predictions(labels, rmse_features, split),
            "rest_frame_rmse_linear": linear_fit_predictions(labels, rest_features, split),
            "one_finger_rmse_linear": linear_fit_predictions(labels, rmse_features[:, :1], split)}
