"""Fit the MLP of one input modality on every fold; predict test and unseen-volume lifts."""

from __future__ import annotations

import itertools
import time

import numpy as np
import pandas as pd

from tactilepipe.core.metrics import r2_score
from tactilepipe.volume.mlp import MLPConfig, MLPRegressor


def feature_columns(axes: list[str], sensor: int) -> list[str]:
    return [f"{axis}{sensor}" for axis in axes]


def fit_modality(data: pd.DataFrame, folds: list[dict], axes: list[str], sensor: int,
                 cfg: MLPConfig, seed: int) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Returns (predictions, per-fold summary).

    predictions: fold, lift, set (test/unseen), volume_ml, pred_ml (one row per sample).
    summary: fold, r2, fit_s, predict_us_per_sample, n_iter, converged, n_train.
    """
    cols = feature_columns(axes, sensor)
    x_all = data[cols].to_numpy(np.float64)
    unseen = (data["set"] == "unseen").to_numpy()
    preds, summary = [], []
    for fold in folds:
        train = data["lift"].isin(fold["train"]).to_numpy()
        test = data["lift"].isin(fold["test"]).to_numpy()
        t0 = time.perf_counter()
        model = MLPRegressor(cfg, seed=seed + 97 * fold["fold"]).fit(x_all[train], data.loc[train, "volume_ml"])
        fit_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        y_test = model.predict(x_all[test])
        predict_us = (time.perf_counter() - t0) / max(1, test.sum()) * 1e6
        summary.append({"fold": fold["fold"], "r2": r2_score(data.loc[test, "volume_ml"], y_test),
                        "fit_s": fit_s, "predict_us_per_sample": predict_us, "n_iter": model.n_iter,
                        "converged": model.converged, "n_train": int(train.sum())})
        for mask, name, y in ((test, "test", y_test), (unseen, "unseen", None)):
            if not mask.any():
                continue
            part = data.loc[mask, ["lift", "volume_ml"]].copy()
            part["pred_ml"] = y if y is not None else model.predict(x_all[mask])
            part.insert(0, "set", name)
            part.insert(0, "fold", fold["fold"])
            preds.append(part)
    return pd.concat(preds, ignore_index=True), pd.DataFrame(summary)


def grid_search(data: pd.DataFrame, fold: dict, axes: list[str], sensor: int, base: MLPConfig,
                grid: dict, seed: int) -> pd.DataFrame:
    """Lift-grouped inner cross-validation over the grid on one fold's training lifts."""
    cols = feature_columns(axes, sensor)
    lifts = np.array(sorted(fold["train"]))
    rng = np.random.default_rng(np.random.SeedSequence([seed, 777]))
    groups = np.array_split(rng.permutation(lifts), grid["inner_folds"])
    rows = []
    for hidden, alpha, lr in itertools.product(grid["hidden_units"], grid["alpha"], grid["learning_rate"]):
        cfg = MLPConfig(**{**base.__dict__, "hidden_units": hidden, "alpha": alpha, "learning_rate": lr})
        scores, fit_s = [], 0.0
        for k, held in enumerate(groups):
            val = data["lift"].isin(held).to_numpy()
            train = data["lift"].isin(lifts).to_numpy() & ~val
            t0 = time.perf_counter()
            model = MLPRegressor(cfg, seed=seed + k).fit(data.loc[train, cols], data.loc[train, "volume_ml"])
            fit_s += time.perf_counter() - t0
            scores.append(r2_score(data.loc[val, "volume_ml"], model.predict(data.loc[val, cols].to_numpy())))
        rows.append({"hidden_units": hidden, "alpha": alpha, "learning_rate": lr,
                     "r2_mean": float(np.mean(scores)), "r2_std": float(np.std(scores)), "fit_s": fit_s})
    out = pd.DataFrame(rows).sort_values("r2_mean", ascending=False, ignore_index=True)
    out["rank"] = np.arange(1, len(out) + 1)
    return out
