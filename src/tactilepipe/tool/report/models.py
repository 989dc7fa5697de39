"""Tool scene results: scores.json, metrics/, tables and the model figures, from the trained runs.

Runs live in results/<build>/<scene>/models/<run>/ (eval.json, predictions.parquet); their names are
explained in ``tool/runs.py``. A model's score (``mae``, ``rmse``, ``r2``) is its mean over the
repeated splits, with the interval beside it (``over_splits``), paired differences between variants
and each variant's verdict against the baselines that have its information (its params.yaml
``tool_variants`` entry's ``baseline``). One split, the first (repeat 0 of the default split), is
what the per-run figures and the ``variants`` table draw: its values sit under ``first_split``,
named so, and every figure drawn from it names it.

scores.json holds all of it; metrics/<variant>.json (DVC's metrics: `dvc metrics show`, `dvc exp
show`) only the headline, each variant's mean scores, a row each (core/metric_rows.py).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.core.atomic import write_json
from tactilepipe.core.errors import TactilepipeError
from tactilepipe.core.intervals import interval
from tactilepipe.core.metric_rows import write_metric_rows
from tactilepipe.core.tables import write_table
from tactilepipe.tool.report import figures_models as fm
from tactilepipe.tool.report import verdicts
from tactilepipe.core.tool_vocabulary import BASELINES
from tactilepipe.tool.model.variants import defined_variants
from tactilepipe.tool.model.evaluate import baselines, evaluate, rest_frame_rmse_features, tactile_rmse_features
from tactilepipe.tool.data.loader import ToolFrames
from tactilepipe.tool.runs import run_spec, sweep_run_name
from tactilepipe.tool.scenes import scene_label
from tactilepipe.tool.data.splits import parse_split_name

FIRST_SPLIT_KEYS = ("mae", "rmse", "r2", "slope", "intercept")          # scores of one split
RUN_KEYS = ("parameters", "epochs", "depth", "image_size")                 # the same for every split


@dataclass
class RunPlan:
    repeats: dict[str, list[str]] = field(default_factory=dict)    # variant -> run of each repeat, repeat 0 first
    loto: dict[str, str] = field(default_factory=dict)             # held-out tool -> run
    sweep: list[str] = field(default_factory=list)


def plan_runs(tool_train: dict, runs: list[str]) -> RunPlan:
    """Which role each run plays; every variant must have the same repeats 0..K-1."""
    plan, by_repeat = RunPlan(), {}
    sweep = {sweep_run_name(s) for s in tool_train["sweep"]}
    for run in runs:
        variant, split, _depth, _size = run_spec(tool_train, run)
        kind, repeat, tool = parse_split_name(split)
        if run in sweep:
            plan.sweep.append(run)
        elif kind == "loto":
            plan.loto[tool] = run
        else:
            by_repeat.setdefault(variant, {})[repeat] = run
    for v in tool_train["variants"]:
        reps = by_repeat.get(v, {})
        if sorted(reps) != list(range(len(reps))) or not reps:
            raise TactilepipeError(f"tool report: variant {v} has runs for repeats {sorted(reps)}; "
                                   "every variant needs repeats 0..K-1")
        plan.repeats[v] = [reps[k] for k in range(len(reps))]
    counts = {len(r) for r in plan.repeats.values()}
    if len(counts) != 1:
        raise TactilepipeError(f"tool report: variants have different numbers of repeats "
                               f"({ {v: len(r) for v, r in plan.repeats.items()} })")
    return plan


def _load(run_dir: Path) -> tuple[dict, pd.DataFrame]:
    return json.loads((run_dir / "eval.json").read_text()), pd.read_parquet(run_dir / "predictions.parquet")


def _test_table(data: ToolFrames, test: np.ndarray, pred: np.ndarray) -> pd.DataFrame:
    s = data.samples.iloc[test]
    return pd.DataFrame({"trial": s["trial"].to_numpy(), "tool": s["tool"].to_numpy(), "t_s": s["t_s"].to_numpy(),
                         "true": data.labels[test].astype(float), "pred": np.asarray(pred, float)})


def baseline_draws(data: ToolFrames, splits: list[dict]) -> list[dict[str, dict]]:
    """Per split: every baseline refitted on its training rows and evaluated on its test rows."""
    rmse_feats = tactile_rmse_features(data.frames, data.references, data.trial_index)
    out = []
    for split in splits:
        rest = rest_frame_rmse_features(data.frames, data.references, data.trial_index, split["train"])
        test = np.asarray(split["test"])
        out.append({name: evaluate(_test_table(data, test, pred))
                    for name, pred in baselines(data.labels, rmse_feats, rest, split).items()})
    return out


def build_model_report(scene_dir: Path, scene: str, tool_train: dict, tool_variants: dict, runs: list[str],
                       equivalence_margin: float) -> dict:
    """scores.json, metrics/, tables and figures of ``runs``; ``tool_train`` and ``tool_variants`` are the
    resolved parameter groups (tool_train.variants a list: core.config.resolve spells out "all");
    ``equivalence_margin`` is params.yaml's tool_report.equivalence_margin (tool/report/verdicts.py)."""
    label = scene_label(scene)
    looks = defined_variants(tool_variants)
    models, tables, figs = scene_dir / "models", scene_dir / "tables", scene_dir / "figures"
    plan = plan_runs(tool_train, runs)
    variants = list(plan.repeats)
    evals, preds = {}, {}
    for run in runs:
        evals[run], preds[run] = _load(models / run)
    k_repeats = len(plan.repeats[variants[0]])
    split_names = [evals[plan.repeats[variants[0]][k]]["split"] for k in range(k_repeats)]
    for v in variants:
        got = [evals[r]["split"] for r in plan.repeats[v]]
        if got != split_names:
            raise TactilepipeError(f"tool report: {v} was trained on splits {got}, {variants[0]} on {split_names}")
    splits = [json.loads((scene_dir / "splits" / f"{name}.json").read_text()) for name in split_names]
    ratio = float(np.mean([len(s["test"]) / len(s["train"]) for s in splits]))

    data = ToolFrames(scene_dir / "data", label)
    base = baseline_draws(data, splits)
    scores = {v: {m: [evals[r][m] for r in plan.repeats[v]] for m in verdicts.METRICS} for v in variants}
    scores |= {b: {m: [draw[b][m] for draw in base] for m in verdicts.METRICS} for b in BASELINES}
    summary = {name: verdicts.over_draws(s, ratio) for name, s in scores.items()}

    # --- scores.json, metrics/ --------------------------------------------------------------------
    metrics = {}
    for v in variants:
        e0 = evals[plan.repeats[v][0]]
        own = [looks[v].baseline, "mean_predictor"]
        against = {b: verdicts.versus(scores[v], scores[b], ratio) for b in own}
        metrics[v] = _mean_scores(summary[v]) | {k: e0[k] for k in RUN_KEYS} | {
            "first_split": _first_split(split_names[0], e0), "per_split": scores[v], "over_splits": summary[v]}
        if v != "full" and "full" in scores:
            metrics[v]["minus_full"] = verdicts.minus(scores[v], scores["full"], ratio)
        metrics[v] |= {"like_for_like_baseline": looks[v].baseline, "versus_baselines": against,
                       "beats_baselines": all(a["beats"] for a in against.values())}
    metrics["baselines"] = {b: _mean_scores(summary[b]) | {"first_split": _first_split(split_names[0], base[0][b]),
                                                           "per_split": scores[b], "over_splits": summary[b]}
                            for b in BASELINES}
    rows, text = verdicts.order_by_mae({v: scores[v] for v in variants}, ratio)
    metrics["ablation_order_by_mae"] = [r["method"] for r in rows]
    metrics["ablation_ranking_by_mae"] = text
    metrics["ablation_ranking_rows"] = rows
    margin = verdicts.margin_n(scores, equivalence_margin)
    metrics["equivalence_margin"] = {"fraction_of_full_mae": equivalence_margin, "n": margin}
    metrics["paper_orderings"] = verdicts.paper_orderings(scene, {v: scores[v] for v in variants}, ratio, margin)
    if "full" in scores:          # the like-for-like baseline, judged the same four ways
        metrics["full_versus_baseline"] = verdicts.judge("full", looks["full"].baseline, scores, margin, ratio)
    metrics["beats_baselines"] = {v: metrics[v]["beats_baselines"] for v in variants}
    metrics["every_variant_beats_baselines"] = all(metrics["beats_baselines"].values())
    metrics["first_split"] = {"split": split_names[0], "test_pairs": int(len(splits[0]["test"]))}
    metrics["splits"] = split_names
    metrics["repeats"] = k_repeats
    metrics["test_pairs_per_split"] = [len(s["test"]) for s in splits]
    metrics["test_train_ratio"] = ratio
    if plan.loto:
        per_tool = {t: {m: evals[r][m] for m in ("mae", "rmse", "r2", "n")} for t, r in sorted(plan.loto.items())}
        loto_splits = [json.loads((scene_dir / "splits" / f"{evals[r]['split']}.json").read_text())
                       for r in plan.loto.values()]
        loto_ratio = float(np.mean([len(s["test"]) / len(s["train"]) for s in loto_splits]))
        metrics["loto"] = {"per_tool": per_tool, "over_tools": {
            m: interval([p[m] for p in per_tool.values()], test_train_ratio=loto_ratio) for m in verdicts.METRICS}}
    write_json(scene_dir / "scores.json", metrics)
    write_metric_rows(scene_dir, headline(metrics, variants))

    # --- tables ---------------------------------------------------------------------------------
    split0_rows = []
    for name in [*variants, *BASELINES]:
        e = evals[plan.repeats[name][0]] if name in plan.repeats else base[0][name]
        split0_rows.append({"model": name, "MAE (N)": e["mae"], "RMSE (N)": e["rmse"], "R²": e["r2"],
                            "slope": e["slope"], "intercept (N)": e["intercept"], "train (s)": e.get("train_s", np.nan),
                            "latency (ms)": e.get("latency_ms", np.nan), "parameters": e.get("parameters", 0)})
    write_table(pd.DataFrame(split0_rows), tables / "variants",
                f"{scene}: test set of the first split, '{split_names[0]}' ({len(splits[0]['test'])} frame pairs)", "{:.4f}")
    write_table(_interval_table(summary), tables / "intervals",
                f"{scene}: over {k_repeats} repeats of the '{split_names[0]}' split (own trials and model seed each), "
                "mean ± std and 95 % interval (Nadeau-Bengio corrected)", "{:.3f}")
    write_table(_differences_table(metrics, variants), tables / "differences",
                f"{scene}: paired differences over the {k_repeats} repeats, 95 % intervals", "{:.3f}")
    write_table(_orderings_table(metrics), tables / "paper_orderings",
                f"{scene}: the study's orderings of the variants, and the full model against its like-for-like "
                f"baseline, judged on the paired MAE difference (worse − better) over the {k_repeats} repeats: "
                f"holds, reversed, equivalent (95 % interval inside ±margin, {equivalence_margin:g} of the full "
                "model's mean MAE) or undecided, with the repeats that would decide it"
                + ("" if metrics["paper_orderings"] else
                   f" (none: no ordering is between two of {', '.join(variants)})"), "{:.3f}",
                machine_only=("equivalence_p", "repeats_to_order", "repeats_to_equivalence"))   # the power line says them
    pt = pd.concat([pd.DataFrame(evals[plan.repeats[v][0]]["per_tool"]).assign(model=v) for v in variants],
                   ignore_index=True)
    pw = pd.concat([pd.DataFrame(evals[plan.repeats[v][0]]["per_window"]).assign(model=v) for v in variants],
                   ignore_index=True)
    on_first = f"test set of the first split, '{split_names[0]}'"
    write_table(pt[["model", "tool", "mae", "std_abs_error", "n"]], tables / "per_tool",
                f"|error| per tool (N), {on_first}", "{:.3f}")
    write_table(pw[["model", "window", "mae", "std_abs_error", "n"]], tables / "per_window",
                f"|error| per force window (N), with frame counts, {on_first}", "{:.3f}")
    every = pd.DataFrame([{"run": r, "variant": evals[r]["variant"], "split": evals[r]["split"],
                           "depth": evals[r]["depth"], "image_size": evals[r]["image_size"], "mae": evals[r]["mae"],
                           "r2": evals[r]["r2"], "train_s": evals[r]["train_s"], "latency_ms": evals[r]["latency_ms"],
                           "parameters": evals[r]["parameters"]} for r in runs])
    write_table(every, tables / "runtime", "Error against run time: every model trained (CPU)", "{:.4f}")
    if plan.loto:
        loto = pd.DataFrame([{"held-out tool": t, **p} for t, p in metrics["loto"]["per_tool"].items()])
        write_table(loto, tables / "loto", "Full model, leave-one-tool-out: each tool held out in turn", "{:.3f}")
    # run times change on every run: kept apart so a metrics diff shows what the results did
    write_json(scene_dir / "runtime.json", {r: {"train_s": float(evals[r]["train_s"]),
                                                "latency_ms": float(evals[r]["latency_ms"])} for r in runs})

    # --- figures: the paper's Figs. 5-8 and 9 (normal) / 10 (shear), on the first split -------------
    p0 = {v: preds[plan.repeats[v][0]] for v in variants}
    e0 = {v: evals[plan.repeats[v][0]] for v in variants}
    first = split_names[0]
    fm.sorted_predictions(p0["full"], label, figs / "sorted_predictions.png", split=first)
    fm.over_time(p0, label, figs / "over_time.png", looks=looks, split=first)
    fm.per_tool_bars({v: pd.DataFrame(e0[v]["per_tool"]) for v in variants}, figs / "per_tool.png", looks=looks,
                     split=first)
    fm.window_heatmap({v: pd.DataFrame(e0[v]["per_window"]) for v in variants}, figs / "window_heatmap.png",
                      looks=looks, split=first)
    fm.regression_grid(p0, e0, label, figs / "regression.png", looks=looks, split=first)
    fm.pareto(every, figs / "error_vs_runtime.png", looks=looks)
    fm.interval_bars(scores, summary, label, figs / "intervals.png", looks=looks)
    if plan.loto:
        fm.loto_bars(metrics["loto"], label, figs / "loto.png", looks=looks)
    return metrics


def _orderings_table(metrics: dict) -> pd.DataFrame:
    """The judged orderings, then the full model against its baseline; repeats as integers or blank."""
    rows = metrics["paper_orderings"] + ([metrics["full_versus_baseline"]] if "full_versus_baseline" in metrics else [])
    table = pd.DataFrame(rows, columns=verdicts.ORDERING_FIELDS).drop(columns=["better", "worse"])
    for col in ("repeats_to_order", "repeats_to_equivalence"):
        table[col] = table[col].astype("Int64")
    table["excludes_zero"] = table["excludes_zero"].map({True: "yes", False: "no"})
    return table


def _mean_scores(over_splits: dict[str, dict]) -> dict[str, float]:
    """A model's scores: the mean of each over the repeated splits (its interval is in over_splits)."""
    return {m: over_splits[m]["mean"] for m in verdicts.METRICS}


def _first_split(name: str, e: dict) -> dict:
    """One split's scores, under a key that says which: the split the figures and the variants table draw."""
    return {"split": name} | {k: e[k] for k in FIRST_SPLIT_KEYS}


def headline(scores: dict, variants: list[str]) -> dict[str, dict]:
    """DVC's metrics, a row per variant (core/metric_rows.py): its mean scores over the repeated
    splits. The intervals, the first split, the baselines and the verdicts are in scores.json."""
    return {v: {m: scores[v][m] for m in verdicts.METRICS} for v in variants}


def _interval_table(summary: dict[str, dict]) -> pd.DataFrame:
    rows = []
    for name, s in summary.items():
        row = {"model": name, "repeats": s["mae"]["n"]}
        for m, title in (("mae", "MAE (N)"), ("rmse", "RMSE (N)"), ("r2", "R²")):
            row[f"{title} mean"] = s[m]["mean"]
            row[f"{title} std"] = s[m]["std"]
            row[f"{title} 95 % low"] = s[m]["low"]
            row[f"{title} 95 % high"] = s[m]["high"]
        rows.append(row)
    return pd.DataFrame(rows)


def _differences_table(metrics: dict, variants: list[str]) -> pd.DataFrame:
    """Each ablation minus full, then each variant's improvement on its baselines (MAE: baseline -
    variant, R²: variant - baseline), with "beats" when both improvements' intervals lie above zero."""
    rows = []
    row = lambda comparison, metric, d, verdict: {
        "comparison": comparison, "metric": metric, "mean": d["mean"], "95 % low": d["low"], "95 % high": d["high"],
        "interval excludes 0": "yes" if d["excludes_zero"] else "no", "verdict": verdict}
    for v in variants:
        for m, d in metrics[v].get("minus_full", {}).items():
            rows.append(row(f"{v} − full", m, d, ""))
        for b, a in metrics[v]["versus_baselines"].items():
            for m in ("mae", "r2"):
                rows.append(row(f"{v} improves on {b}", m, a[f"{m}_improvement"],
                                "beats" if a["beats"] else "not shown to beat"))
    return pd.DataFrame(rows)
