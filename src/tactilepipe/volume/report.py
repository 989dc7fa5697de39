"""Volume scene results: scores.json (every number) and metrics/ (its headline), Tables 1-2,
unseen volumes, run time, and the figures."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from tactilepipe.core.atomic import write_json
from tactilepipe.core.intervals import interval, paired_difference, ranking, ranking_text
from tactilepipe.core.metric_rows import write_metric_rows
from tactilepipe.core.metrics import R2_CONSTANT, format_metric
from tactilepipe.core.simulated import mixed_data_note
from tactilepipe.core.tables import write_table
from tactilepipe.volume import figures


def headline(scores: dict) -> dict[str, dict]:
    """DVC's metrics, a row per input and one for the baseline (core/metric_rows.py): its mean R²
    over the folds; the best MLP's row adds its paired gain on the baseline (``r2_gain``), the
    baseline's its μ*. The folds, intervals, tables and QC names are in scores.json beside them."""
    rows = {m: {"r2": v["mean"]} for m, v in scores["r2"].items()}
    rows[scores["best_minus_baseline"]["modality"]]["r2_gain"] = scores["best_minus_baseline"]["mean"]
    rows["baseline"]["mu_star"] = scores["mu_star"]
    return rows


def _summary(folds: pd.DataFrame, test_train_ratio: float) -> dict:
    """Mean and std of R² over the folds where it is defined (the std as study 001 reports it,
    over the folds, ddof 0), the 95 % interval of the mean (corrected for the folds' shared
    training data), and how many folds have no R²."""
    r2 = folds.sort_values("fold")["r2"].to_numpy(np.float64)
    ok = np.isfinite(r2)
    ci = interval(r2, test_train_ratio=test_train_ratio)
    return {"mean": float(r2[ok].mean()) if ok.any() else float("nan"),
            "std": float(r2[ok].std()) if ok.any() else float("nan"),
            "ci95": [ci["low"], ci["high"]],
            "folds": [float(v) for v in r2], "undefined_folds": int((~ok).sum())}


def _interval_text(s: dict) -> str:
    low, high = s["ci95"]
    return f"[{format_metric(low)}, {format_metric(high)}]" if np.isfinite(low) else "undefined (under 2 folds)"


def _r2_text(s: dict) -> str:
    """Table 1's cell: "mean ± std", or "undefined" with how many folds have no R²."""
    n = len(s["folds"])
    if s["undefined_folds"] == n:
        return f"undefined ({R2_CONSTANT.split(': ', 1)[1]} in all {n} folds)"
    text = f"{format_metric(s['mean'])} ± {format_metric(s['std'])}"
    return text + (f" ({s['undefined_folds']} of {n} folds undefined)" if s["undefined_folds"] else "")


def _json_safe(x):
    """NaN/inf -> None so scores.json stays strict JSON ("undefined" has a reason elsewhere)."""
    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if np.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def _peak_pillar_forces(shard: Path) -> tuple[np.ndarray, float]:
    cols = [f"f{a}{i}" for i in range(9) for a in "xyz"]
    df = pq.read_table(shard, columns=["sensor", "stamp_ns", "gfy", *cols]).to_pandas()
    df = df[df["sensor"].notna()]
    s0, s1 = (df[df["sensor"] == s].reset_index(drop=True) for s in (0, 1))
    k = int(s0["gfy"].abs().idxmax())
    forces = np.stack([s[cols].to_numpy().reshape(-1, 9, 3)[min(k, len(s) - 1)] for s in (s0, s1)])
    return forces, (s0["stamp_ns"][k] - s0["stamp_ns"][0]) / 1e9


def _read_qc(qc_path: Path) -> pd.DataFrame:
    """The data set's per-lift QC table (volume/dataset.py), read once for every note drawn from it."""
    return pd.read_csv(qc_path, dtype={"stands_out": str, "session": str}, keep_default_na=False)


def _slipped_lifts(qc: pd.DataFrame) -> list[str]:
    """Lifts left out of the models because their grasp slid off the table (volume/dataset.py)."""
    return sorted(qc.loc[qc["slipped"], "lift"]) if "slipped" in qc else []


def _lifts_left_out(qc: pd.DataFrame) -> dict[str, str]:
    """Lifts left out of the models because their sensors stood out from their session's, with
    the evidence (volume/witness.py)."""
    if "stands_out" not in qc:
        return {}
    out = qc[qc["stands_out"] != ""]
    return dict(sorted(zip(out["lift"], out["stands_out"])))


def build_report(res: Path, p: dict, raw_root: Path, shard_root: Path) -> dict:
    modalities = list(p["mlp"]["modalities"])
    fold_tables = {m: pd.read_csv(res / "mlp" / m / "folds.csv") for m in modalities}
    fold_tables["baseline"] = pd.read_csv(res / "baseline" / "folds.csv")
    ratio = p["folds"]["test_lifts_per_volume"] / p["folds"]["train_lifts_per_volume"]
    r2 = {m: _summary(t, ratio) for m, t in fold_tables.items()}
    best = max(modalities, key=lambda m: r2[m]["mean"] if np.isfinite(r2[m]["mean"]) else -np.inf)
    # the best MLP against the baseline, fold by fold (same test lifts): the difference's interval
    best_vs_baseline = paired_difference(r2[best]["folds"], r2["baseline"]["folds"], test_train_ratio=ratio)
    mu = json.loads((res / "baseline" / "mu.json").read_text())
    mu_edge = [o for o in mu["optima"] if o.get("on_edge")]
    mu_notes = [o["note"] for o in mu["optima"] if o.get("note")]
    preds = pd.read_parquet(res / "mlp" / best / "predictions.parquet")

    # Table 1 and the run-time table
    def method_label(m: str) -> str:
        text = figures.label(m).replace("\n", " ")
        if m == "baseline" and mu_edge:
            text += f" [mu optimum on the sweep edge in {len(mu_edge)} of {len(mu['optima'])} folds]"
        return text

    table1 = pd.DataFrame([{"method": method_label(m), "R² (mean ± std)": _r2_text(r2[m]),
                            "95 % interval": _interval_text(r2[m]),
                            "r2_mean": r2[m]["mean"], "r2_std": r2[m]["std"],
                            "ci95_low": r2[m]["ci95"][0], "ci95_high": r2[m]["ci95"][1]} for m in r2])
    d = best_vs_baseline
    table1 = pd.concat([table1, pd.DataFrame([{
        "method": f"paired difference: MLP {best} − baseline",
        "R² (mean ± std)": f"{format_metric(d['mean'])} ± {format_metric(d['std'])} (std ddof 1)",
        "95 % interval": f"[{format_metric(d['low'])}, {format_metric(d['high'])}]"
                         + (" excludes 0" if d["excludes_zero"] else " includes 0"),
        "r2_mean": d["mean"], "r2_std": d["std"], "ci95_low": d["low"], "ci95_high": d["high"]}])],
        ignore_index=True)
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
    qc = _read_qc(res / "qc.csv")
    mixed = mixed_data_note(qc["session"], "lift")
    write_table(table1, tables / "table1_r2", "Table 1: R² on test lifts (mean ± std over folds; 95 % "
                "interval of the mean, t with the resampled-folds correction)" + (f". {mixed}" if mixed else ""),
                machine_only=("r2_mean", "r2_std", "ci95_low", "ci95_high"))
    write_table(table2, tables / "table2_volumes", f"Table 2: true vs estimated volume, MLP {best}", "{:.2f}")
    write_table(unseen_table, tables / "unseen_volumes", f"Unseen volumes, MLP {best}", "{:.2f}")
    write_table(runtime, tables / "runtime", "Error against run time (fit per fold, predict per sample)")
    grid = pd.read_csv(res / "mlp" / "grid.csv")
    write_table(grid, tables / "grid_search", f"MLP grid search ({p['mlp']['grid']['modality']}, "
                 f"lift-grouped {p['mlp']['grid']['inner_folds']}-fold CV on fold d1's training lifts)")

    figs = res / "figures"
    figures.r2_bars(r2, figs / "r2_by_modality.png")
    curve = pd.read_csv(res / "baseline" / "mu_curve.csv")
    figures.mu_curves(curve, pd.DataFrame(mu["optima"]), mu["mu_star"], figs / "mu_r2_curve.png",
                      warning="optimum on the edge of the swept range" if mu_edge else None)
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
        "r2_ci95": {m: v["ci95"] for m, v in r2.items()},
        "best_minus_baseline": {"modality": best, "mean": best_vs_baseline["mean"],
                                "ci95": [best_vs_baseline["low"], best_vs_baseline["high"]],
                                "per_fold": best_vs_baseline["per_draw"],
                                "beats_baseline": bool(best_vs_baseline["excludes_zero"]
                                                       and best_vs_baseline["mean"] > 0)},
        "mu_star": mu["mu_star"],
        "mu_optimum_on_edge": bool(mu_edge),
        "mu_warnings": mu_notes,
        "r2_undefined": {m: f"{v['undefined_folds']} of {len(v['folds'])} folds: {R2_CONSTANT}"
                         for m, v in r2.items() if v["undefined_folds"]},
        "best_modality": best,
        "modality_order": ordering,
        # neighbours in that order that the paired intervals over the folds cannot tell apart read '≈'
        "modality_ranking": ranking_text(ranking({m: r2[m]["folds"] for m in ordering}, True,
                                                 test_train_ratio=ratio)),
        "unseen_ml": {f"{v:g}": float(e) for v, e in zip(unseen_table["true_ml"], unseen_table["estimated_ml"])},
        "table2_ml": {f"{v:g}": float(e) for v, e in zip(table2["true_ml"], table2["estimated_ml"])},
        "grid_best": grid.iloc[0][["hidden_units", "alpha", "learning_rate", "r2_mean"]].to_dict(),
        "scale": p["scale"],
        "lifts_slipped": _slipped_lifts(qc),
        "lifts_standing_out": _lifts_left_out(qc),
    } | ({"mixed_data": mixed} if mixed else {})
    metrics = _json_safe(metrics)
    write_json(res / "scores.json", metrics)
    write_metric_rows(res, headline(metrics))
    # run times change on every run: kept apart so a metrics diff shows what the results did
    write_json(res / "runtime.json", _json_safe({r.method: {"fit_s": r.fit_s,
                                                             "predict_us_per_sample": r.predict_us_per_sample}
                                                 for r in runtime.itertuples()}))
    return metrics
