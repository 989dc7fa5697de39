"""Evaluation of tool-force predictions on the full set of test predictions (never per batch).

Overall MAE, RMSE, R², regression slope/intercept; |error| per tool (mean ± std, n) and per
force window (0–3, 3–6, …, >21 N, with counts); and two baselines on the same split: the mean
predictor (training mean) and a linear fit on the tactile RMSE of each finger against its
reference frame.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tactilepipe.metrics import mae, r2_score, rmse

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


def baselines(labels: np.ndarray, features: np.ndarray, split: dict) -> dict[str, np.ndarray]:
    """Test predictions of the mean predictor and of a least-squares fit on the tactile RMSE."""
    train, test = np.asarray(split["train"]), np.asarray(split["test"])
    mean_pred = np.full(len(test), labels[train].mean())
    design = lambda idx: np.column_stack([features[idx], np.ones(len(idx))])
    coef, *_ = np.linalg.lstsq(design(train), labels[train], rcond=None)
    return {"mean_predictor": mean_pred, "tactile_rmse_linear": design(test) @ coef}


def beats_baselines(evals: dict[str, dict], base_evals: dict[str, dict]) -> dict[str, bool]:
    """Per variant: lower MAE and higher R² than every baseline (one metric alone is not "beats")."""
    return {v: all(e["mae"] < b["mae"] and e["r2"] > b["r2"] for b in base_evals.values())
            for v, e in evals.items()}
