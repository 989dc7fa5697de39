"""Volume scene results: metrics.json, Tables 1-2, unseen volumes, run time, and the figures."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from tactilepipe.atomic import write_json
from tactilepipe.tables import write_table
from tactilepipe.volume import figures


def _summary(folds: pd.DataFrame) -> dict:
    return {"mean": float(folds["r2"].mean()), "std": float(folds["r2"].std(ddof=0)),
            "folds": [float(v) for v in folds["r2"]]}


def _peak_pillar_forces(shard: Path) -> tuple[np.ndarray, float]:
    cols = [f"f{a}{i}" for i in range(9) for a in "xyz"]
    df = pq.read_table(shard, columns=["sensor", "stamp_ns", "gfy", *cols]).to_pandas()
    df = df[df["sensor"].notna()]
    s0, s1 = (df[df["sensor"] == s].reset_index(drop=True) for s in (0, 1))
    k = int(s0["gfy"].abs().idxmax())
    forces = np.stack([s[cols].to_numpy().reshape(-1, 9, 3)[min(k, len(s) - 1)] for s in (s0, s1)])
    return forces, (s0["stamp_ns"][k] - s0["stamp_ns"][0]) / 1e9


def build_report(res: Path, p: dict, raw_root: Path, shard_root: Path) -> dict:
    modalities = list(p["mlp"]["modalities"])
    fold_tables = {m: pd.read_csv(res / "mlp" / m / "folds.csv") for m in modalities}
    fold_tables["baseline"] = pd.read_csv(res / "baseline" / "folds.csv")
    r2 = {m: _summary(t) for m, t in fold_tables.items()}
    best = max(modalities, key=lambda m: r2[m]["mean"])
    mu = json.loads((res / "baseline" / "mu.json").read_text())
    preds = pd.read_parquet(res / "mlp" / best / "predictions.parquet")

    # Table 1 and the run-time table
    table1 = pd.DataFrame([{"method": figures.label(m).replace("\n", " "),
                            "R² (mean ± std)": f"{r2[m]['mean']:.4f} ± {r2[m]['std']:.4f}",
                            "r2_mean": r2[m]["mean"], "r2_std": r2[m]["std"]} for m in r2])
    runtime = pd.DataFrame([{"method": m, "r2_mean": r2[m]["mean"], "r2_std": r2[m]["std"],
                             "fit_s": float(t["fit_s"].mean()),
                             "predict_us_per_sample": float(t["predict_us_per_sample"].mean()),
                             "epochs": float(t["n_iter"].mean()) if "n_iter" in t else float("nan")}
                            for m, t in fold_tables.items()])
    # Table 2: true vs mean estimate per class, best MLP, over all test samples of all folds
    test = preds[preds["set"] == "test"]
    table2 = (test.groupby("volume_ml")["pred_ml"].agg(["mean", "std"]).reset_index()
              .rename(columns={"volume_ml": "true_ml", "mean": "estimated_ml", "std": "std_ml"}))
    unseen = preds[preds["set"] == "unseen"]
    per_fold_unseen = unseen.groupby(["volume_ml", "fold"])["pred_ml"].mean().reset_index()
    unseen_table = (per_fold_unseen.groupby("volume_ml")["pred_ml"].agg(["mean", "std"]).reset_index()
                    .rename(columns={"volume_ml": "true_ml", "mean": "estimated_ml", "std": "std_over_folds_ml"}))
    unseen_table["abs_error_ml"] = (unseen_table["estimated_ml"] - unseen_table["true_ml"]).abs()

    tables = res / "tables"
    write_table(table1, tables / "table1_r2", "Table 1: R² on test lifts (mean ± std over folds)")
    write_table(table2, tables / "table2_volumes", f"Table 2: true vs estimated volume, MLP {best}", "{:.2f}")
    write_table(unseen_table, tables / "unseen_volumes", f"Unseen volumes, MLP {best}", "{:.2f}")
    write_table(runtime, tables / "runtime", "Error against run time (fit per fold, predict per sample)")
    grid = pd.read_csv(res / "mlp" / "grid.csv")
    write_table(grid, tables / "grid_search", f"MLP grid search ({p['mlp']['grid']['modality']}, "
                 f"lift-grouped {p['mlp']['grid']['inner_folds']}-fold CV on fold d1's training lifts)")

    figs = res / "figures"
    figures.r2_bars(r2, figs / "r2_by_modality.png")
    curve = pd.read_csv(res / "baseline" / "mu_curve.csv")
    figures.mu_curves(curve, pd.DataFrame(mu["optima"]), mu["mu_star"], figs / "mu_r2_curve.png")
    per_lift = preds.groupby(["set", "fold", "lift", "volume_ml"])["pred_ml"].mean().reset_index()
    figures.true_vs_estimated(per_lift, best, figs / "true_vs_estimated.png")
    figures.runtime_scatter(runtime, figs / "error_vs_runtime.png")
    heaviest = test[test["volume_ml"] == test["volume_ml"].max()]["lift"].min()
    session, stem = heaviest.split("/", 1)
    forces, t_peak = _peak_pillar_forces(shard_root / session / f"{stem}.parquet")
    figures.pillar_map(forces, f"{heaviest}: peak vertical load at t = {t_peak:.2f} s",
                       figs / "pillar_map.png")

    ordering = sorted(modalities, key=lambda m: -r2[m]["mean"])
    metrics = {
        "r2": {m: {"mean": v["mean"], "std": v["std"]} for m, v in r2.items()},
        "r2_folds": {m: v["folds"] for m, v in r2.items()},
        "mu_star": mu["mu_star"],
        "mu_optimum_on_edge": any(o["on_edge"] for o in mu["optima"]),
        "best_modality": best,
        "modality_order": ordering,
        "unseen_ml": {f"{v:g}": float(e) for v, e in zip(unseen_table["true_ml"], unseen_table["estimated_ml"])},
        "table2_ml": {f"{v:g}": float(e) for v, e in zip(table2["true_ml"], table2["estimated_ml"])},
        "runtime": {r.method: {"fit_s": r.fit_s, "predict_us_per_sample": r.predict_us_per_sample}
                    for r in runtime.itertuples()},
        "grid_best": grid.iloc[0][["hidden_units", "alpha", "learning_rate", "r2_mean"]].to_dict(),
        "scale": p["scale"],
    }
    write_json(res / "metrics.json", metrics)
    return metrics
