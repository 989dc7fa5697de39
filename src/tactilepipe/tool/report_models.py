"""Tool scene results: metrics.json, tables and the model figures, from the trained runs.

Runs live in results/<scene>/models/<run>/ (eval.json, predictions.parquet): one per variant on
the default split, the full model leave-one-tool-out (run "full_loto"), and the backbone/size
sweep (runs "full_d<depth>_s<size>").
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.atomic import write_json, write_text
from tactilepipe.tool import figures_models as fm
from tactilepipe.tool.evaluate import baselines, beats_baselines, evaluate, tactile_rmse_features
from tactilepipe.tool.loader import ToolFrames
from tactilepipe.tables import write_table

def _load(run_dir: Path) -> tuple[dict, pd.DataFrame]:
    return json.loads((run_dir / "eval.json").read_text()), pd.read_parquet(run_dir / "predictions.parquet")


def build_model_report(scene_dir: Path, scene: str, variants: list[str], sweep_runs: list[str]) -> dict:
    label = "normal" if scene == "tool_normal" else "shear"
    models = scene_dir / "models"
    evals, preds = {}, {}
    for v in variants:
        evals[v], preds[v] = _load(models / v)
    split = json.loads((scene_dir / "splits" / f"{evals[variants[0]]['split']}.json").read_text())

    data = ToolFrames(scene_dir / "data", label)
    feats = tactile_rmse_features(data.frames, data.references, data.trial_index)
    test = np.asarray(split["test"])
    base_tables = {}
    for name, pred in baselines(data.labels, feats, split).items():
        s = data.samples.iloc[test]
        base_tables[name] = pd.DataFrame({"trial": s["trial"].to_numpy(), "tool": s["tool"].to_numpy(),
                                          "t_s": s["t_s"].to_numpy(), "true": data.labels[test], "pred": pred})
    base_evals = {k: evaluate(v) for k, v in base_tables.items()}

    rows = []
    for name, e in [*evals.items(), *base_evals.items()]:
        rows.append({"model": name, "MAE (N)": e["mae"], "RMSE (N)": e["rmse"], "R²": e["r2"],
                     "slope": e["slope"], "intercept (N)": e["intercept"],
                     "train (s)": e.get("train_s", np.nan), "latency (ms)": e.get("latency_ms", np.nan),
                     "parameters": e.get("parameters", 0)})
    tables = scene_dir / "tables"
    write_table(pd.DataFrame(rows), tables / "variants",
                 f"{scene}: test set of the '{split['name']}' split ({len(test)} frame pairs)", "{:.4f}")
    per_tool = {v: pd.DataFrame(evals[v]["per_tool"]) for v in variants}
    per_window = {v: pd.DataFrame(evals[v]["per_window"]) for v in variants}
    pt = pd.concat([t.assign(model=v) for v, t in per_tool.items()], ignore_index=True)
    pw = pd.concat([t.assign(model=v) for v, t in per_window.items()], ignore_index=True)
    write_table(pt[["model", "tool", "mae", "std_abs_error", "n"]], tables / "per_tool", "|error| per tool (N)", "{:.3f}")
    write_table(pw[["model", "window", "mae", "std_abs_error", "n"]], tables / "per_window",
                 "|error| per force window (N), with frame counts", "{:.3f}")

    runs = []
    for name in [*variants, *sweep_runs]:
        e = evals[name] if name in evals else _load(models / name)[0]
        runs.append({"name_": name, "variant": e["variant"], "depth": e["depth"], "image_size": e["image_size"],
                     "mae": e["mae"], "r2": e["r2"], "train_s": e["train_s"], "latency_ms": e["latency_ms"],
                     "parameters": e["parameters"]})
    runs = pd.DataFrame(runs)
    write_table(runs.rename(columns={"name_": "run"}), tables / "runtime",
                 "Error against run time: every model trained (2 CPU cores)", "{:.4f}")

    loto = None
    if (models / "full_loto" / "eval.json").exists():
        loto, _ = _load(models / "full_loto")
        write_table(pd.DataFrame(loto["per_tool"]), tables / "loto",
                     f"Full model, leave-one-tool-out: the held-out tool ({loto['split']})", "{:.3f}")

    figs = scene_dir / "figures"
    # the paper's Figs. 5-8 and 9 (normal) / 10 (shear), for both targets
    fm.sorted_predictions(preds["full"], label, figs / "sorted_predictions.png")
    fm.over_time(preds, label, figs / "over_time.png")
    fm.per_tool_bars(per_tool, figs / "per_tool.png")
    fm.window_heatmap(per_window, figs / "window_heatmap.png")
    fm.regression_grid(preds, evals, label, figs / "regression.png")
    fm.pareto(runs, figs / "error_vs_runtime.png")

    order = sorted(variants, key=lambda v: evals[v]["mae"])
    metrics = {v: {k: evals[v][k] for k in ("mae", "rmse", "r2", "slope", "intercept",
                                          "parameters", "epochs", "depth", "image_size")} for v in variants}
    # run times change on every run: kept apart so a metrics diff shows what the results did
    write_json(scene_dir / "runtime.json", {r.name_: {"train_s": float(r.train_s), "latency_ms": float(r.latency_ms)}
                                            for r in runs.itertuples()})
    metrics["baselines"] = {k: {m: v[m] for m in ("mae", "rmse", "r2")} for k, v in base_evals.items()}
    metrics["ablation_order_by_mae"] = order
    metrics["beats_baselines"] = beats_baselines({v: evals[v] for v in variants}, base_evals)
    metrics["every_variant_beats_baselines"] = all(metrics["beats_baselines"].values())
    metrics["split"] = split["name"]
    metrics["test_pairs"] = int(len(test))
    if loto:
        metrics["loto_full"] = {k: loto[k] for k in ("mae", "rmse", "r2")} | {"split": loto["split"]}
    write_json(scene_dir / "metrics.json", metrics)
    return metrics
