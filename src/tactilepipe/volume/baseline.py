"""Study 001's algebraic baseline: est_vol = 1000 (Fy + mu Fz) / G - m_cont, mu swept per fold.

An optimum on the first or last swept mu is flagged (``on_edge`` per fold, a note saying which
edge, and ``warnings``): the curve may still be rising there. A training fold whose volumes are
all equal has no optimum (R² undefined for every mu): its mu_opt is NaN with the reason, and mu*
is the mean of the folds that have one (NaN if none does) - no exception.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from tactilepipe.core.metrics import r2_detail, r2_score


def estimate_volume(fy, fz, mu: float, gravity: float, container_mass_g: float) -> np.ndarray:
    return 1000.0 * (np.asarray(fy) + mu * np.asarray(fz)) / gravity - container_mass_g


def sweep(data: pd.DataFrame, folds: list[dict], sensor: int, p: dict) -> dict:
    """mu-R² curve on every training fold, mu* = mean of the fold optima, applied to the tests."""
    mus = np.linspace(p["mu_min"], p["mu_max"], p["n_mu"])
    fy, fz = data[f"fy{sensor}"].to_numpy(), data[f"fz{sensor}"].to_numpy()
    y = data["volume_ml"].to_numpy()
    curves, optima = [], []
    t0 = time.perf_counter()
    for fold in folds:
        train = data["lift"].isin(fold["train"]).to_numpy()
        r2 = np.array([r2_score(y[train], estimate_volume(fy[train], fz[train], mu, p["gravity"],
                                                          p["container_mass_g"])) for mu in mus])
        if np.isnan(r2).all():      # constant training volumes (one class): R² is undefined everywhere
            reason = r2_detail(y[train], y[train])[1] or "undefined"
            optima.append({"fold": fold["fold"], "mu_opt": float("nan"), "r2_train": float("nan"),
                           "on_edge": False, "note": f"no optimum: R² {reason}"})
        else:
            k = int(np.nanargmax(r2))
            edge = k in (0, len(mus) - 1)
            optima.append({"fold": fold["fold"], "mu_opt": float(mus[k]), "r2_train": float(r2[k]),
                           "on_edge": edge, "note": edge_note(mus[k], p) if edge else ""})
        curves.append(pd.DataFrame({"fold": fold["fold"], "mu": mus, "r2_train": r2}))
    found = [o["mu_opt"] for o in optima if np.isfinite(o["mu_opt"])]
    mu_star = float(np.mean(found)) if found else float("nan")
    fit_s = (time.perf_counter() - t0) / len(folds)
    preds, summary = [], []
    for fold in folds:
        test = data["lift"].isin(fold["test"]).to_numpy()
        t0 = time.perf_counter()
        est = estimate_volume(fy[test], fz[test], mu_star, p["gravity"], p["container_mass_g"])
        predict_us = (time.perf_counter() - t0) / max(1, test.sum()) * 1e6
        r2, reason = r2_detail(y[test], est)
        summary.append({"fold": fold["fold"], "r2": r2, "r2_note": reason or "", "fit_s": fit_s,
                        "predict_us_per_sample": predict_us})
        part = data.loc[test, ["lift", "volume_ml"]].copy()
        part["pred_ml"] = est
        part.insert(0, "set", "test")
        part.insert(0, "fold", fold["fold"])
        preds.append(part)
    optima = pd.DataFrame(optima)
    return {"mu_star": mu_star, "optima": optima, "curve": pd.concat(curves, ignore_index=True),
            "predictions": pd.concat(preds, ignore_index=True), "summary": pd.DataFrame(summary),
            "on_edge": bool(optima["on_edge"].any()), "warnings": [n for n in optima["note"] if n]}


def edge_note(mu: float, p: dict) -> str:
    """Why an optimum on the edge of the sweep is not an optimum: the true one may lie beyond."""
    side = "lower" if np.isclose(mu, p["mu_min"]) else "upper"
    return (f"mu optimum {mu:.4g} on the {side} edge of the swept range [{p['mu_min']:g}, {p['mu_max']:g}]: "
            f"the R² maximum may lie beyond it (widen baseline.mu_min/mu_max)")
