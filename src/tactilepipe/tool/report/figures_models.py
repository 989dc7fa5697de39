"""Figures of the tool-force models (study 000, Figs. 5-10) and the error-against-run-time plot.

Each takes plain tables (predictions with columns true, pred, tool, trial, t_s; metrics dicts),
so a newcomer finds every model figure here. A figure drawn from one split's test set (Figs. 5-10)
takes that split's name and puts it in its title (``on_split``): the scores over every split are
elsewhere (``interval_bars``), and one split's are a single draw of them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.core.atomic import save_figure
from tactilepipe.core.plotting import close, figure, save_figure_data
from tactilepipe.tool.model.variants import Variant

# ``looks``: the variants as params.yaml tool_variants defines them ({name: Variant}), whose label and
# colour the figures draw; a name it does not hold (a baseline) keeps its own name and a neutral colour.


def _colour(looks: dict[str, Variant], name: str, default: str | None = None) -> str | None:
    return looks[name].colour if name in looks else default


def _label(looks: dict[str, Variant], name: str, default: str | None = None) -> str:
    return looks[name].label if name in looks else (default or name)


def on_split(split: str) -> str:
    """How a one-split figure names its split in its title."""
    return f"test set of split '{split}'"


def sorted_predictions(pred: pd.DataFrame, label: str, out: Path, *, split: str) -> None:
    """Fig. 5: test predictions and ground truth, sorted by the true force."""
    order = np.argsort(pred["true"].to_numpy(), kind="stable")
    fig, ax = figure(6.0, 3.2)
    ax.plot(pred["pred"].to_numpy()[order], ".", ms=2, alpha=0.5, color="#4C72B0", label="prediction")
    ax.plot(pred["true"].to_numpy()[order], "-", lw=1.5, color="k", label="ground truth (Nano17)")
    ax.set_xlabel("test frame pairs, sorted by true force")
    ax.set_ylabel(f"{label} force (N)")
    ax.set_title(f"Full model on the {on_split(split)}")
    ax.legend(loc="upper left")
    save_figure(out, fig)
    close(fig)


def strongest_trial_per_tool(pred: pd.DataFrame) -> list[str]:
    """The trial with the highest true force of each tool, tools in name order."""
    peaks = pred.groupby(["tool", "trial"])["true"].max().reset_index()
    return peaks.sort_values(["tool", "true"], ascending=[True, False]).groupby("tool").head(1)["trial"].tolist()


def over_time(preds: dict[str, pd.DataFrame], label: str, out: Path, gap_s: float = 0.5, *, looks: dict[str, Variant],
              split: str) -> None:
    """Fig. 6: predictions over time, per variant, for several presses: the test trial with the
    highest peak of each tool, laid end to end (trials are a few seconds, one or two presses each)."""
    first = next(iter(preds.values()))
    trials = strongest_trial_per_tool(first)
    fig, ax = figure(9.0, 3.4)
    offset = 0.0
    for i, trial in enumerate(trials):
        ref = first[first["trial"] == trial].sort_values("t_s")
        t0 = ref["t_s"].min()
        ax.plot(ref["t_s"] - t0 + offset, ref["true"], color="k", lw=1.8, label="ground truth" if i == 0 else None)
        for variant in ("single", "no_ref", "full"):
            if variant in preds:
                part = preds[variant][preds[variant]["trial"] == trial].sort_values("t_s")
                ax.plot(part["t_s"] - t0 + offset, part["pred"], lw=1.1, color=_colour(looks, variant),
                        label=_label(looks, variant) if i == 0 else None)
        ax.text(offset, 1.0, ref["tool"].iloc[0].replace("_", " "), transform=ax.get_xaxis_transform(),
                va="bottom", fontsize=8)
        offset += ref["t_s"].max() - t0 + gap_s
        if i < len(trials) - 1:
            ax.axvline(offset - gap_s / 2, color="0.7", lw=0.8, ls=":")
    ax.set_xlabel("time within each test trial, trials end to end (s)")
    ax.set_ylabel(f"{label} force (N)")
    ax.set_title(f"Predictions over time: the strongest trial of each tool, {on_split(split)}", pad=14)
    ax.legend(ncols=4, loc="upper center", bbox_to_anchor=(0.5, -0.2), frameon=False)
    save_figure(out, fig)
    close(fig)


def per_tool_bars(per_tool: dict[str, pd.DataFrame], out: Path, *, looks: dict[str, Variant], split: str) -> None:
    """Fig. 7: mean |error| per tool with its std, one bar per variant."""
    variants = list(per_tool)
    tools = sorted(set().union(*(set(t["tool"]) for t in per_tool.values())))
    width = 0.8 / len(variants)
    fig, ax = figure(6.0, 3.4)
    for k, v in enumerate(variants):
        t = per_tool[v].set_index("tool").reindex(tools)
        ax.bar(np.arange(len(tools)) + (k - (len(variants) - 1) / 2) * width, t["mae"], width,
               yerr=t["std_abs_error"], capsize=2, color=_colour(looks, v), label=_label(looks, v))
    ax.set_xticks(range(len(tools)), [t.replace("_", " ") for t in tools])
    ax.set_ylabel("|error| (N), mean ± std")
    ax.set_title(f"Error per tool, {on_split(split)}")
    ax.legend(fontsize=7)
    save_figure(out, fig)
    close(fig)


def window_heatmap(per_window: dict[str, pd.DataFrame], out: Path, *, looks: dict[str, Variant], split: str) -> None:
    """Fig. 8: MAE per force window (columns) and variant (rows), with the frame counts."""
    variants = list(per_window)
    windows = list(per_window[variants[0]]["window"].astype(str))
    grid = np.array([per_window[v].set_index(per_window[v]["window"].astype(str))["mae"].reindex(windows).to_numpy()
                     for v in variants], float)
    counts = per_window[variants[0]]["n"].to_numpy()
    fig, ax = figure(7.0, 0.6 * len(variants) + 1.6)
    im = ax.imshow(grid, cmap="Reds", aspect="auto")
    ax.grid(False)
    for i in range(grid.shape[0]):
        for j in range(grid.shape[1]):
            if np.isfinite(grid[i, j]):
                ax.text(j, i, f"{grid[i, j]:.2f}", ha="center", va="center", fontsize=8,
                        color="white" if grid[i, j] > np.nanmax(grid) * 0.6 else "black")
    ax.set_xticks(range(len(windows)), [f"{w}\nn={c}" for w, c in zip(windows, counts)], fontsize=7)
    ax.set_yticks(range(len(variants)), [_label(looks, v) for v in variants])
    fig.colorbar(im, ax=ax, label="MAE (N)")
    ax.set_title(f"Error per force window, {on_split(split)}")
    save_figure(out, fig)
    close(fig)


def regression_grid(preds: dict[str, pd.DataFrame], metrics: dict[str, dict], label: str, out: Path, *,
                    looks: dict[str, Variant], split: str) -> None:
    """Fig. 9/10: predicted against true force per variant, with R², MAE and the fitted line of the
    split (``metrics``: each variant's scores on it)."""
    variants = list(preds)
    cols = 2 if len(variants) > 1 else 1
    rows = int(np.ceil(len(variants) / cols))
    fig, axes = figure(3.2 * cols, 3.0 * rows, nrows=rows, ncols=cols, squeeze=False)
    hi = max(max(p["true"].max(), p["pred"].max()) for p in preds.values())
    for ax, v in zip(axes.flat, variants):
        p, m = preds[v], metrics[v]
        ax.plot(p["true"], p["pred"], ".", ms=2, alpha=0.35, color=_colour(looks, v, "#4C72B0"))
        ax.plot([0, hi], [0, hi], "k--", lw=0.8)
        xs = np.array([0, hi])
        ax.plot(xs, m["slope"] * xs + m["intercept"], color="k", lw=1.0)
        ax.set_title(f"{_label(looks, v)}\nR² {m['r2']:.4f}, MAE {m['mae']:.3f} N", fontsize=9)
        ax.set_xlabel(f"true {label} (N)")
        ax.set_ylabel(f"predicted {label} (N)")
        ax.set_xlim(-0.5, hi + 0.5)
        ax.set_ylim(-0.5, hi + 0.5)
    for ax in list(axes.flat)[len(variants):]:
        ax.remove()
    fig.suptitle(f"Predicted against true force, {on_split(split)}", fontsize=10)
    save_figure(out, fig)
    close(fig)


def pareto(runs: pd.DataFrame, out: Path, *, looks: dict[str, Variant]) -> None:
    """Error against run time: MAE vs training time and vs inference latency for every model trained
    (columns run, variant, split, mae, train_s, latency_ms). Runs on repeat 0 of the default split
    (the variants and the sweep) are labelled and give the Pareto front, since they share a test
    set; the other repeats and the leave-one-tool-out runs are drawn small, so the spread of one
    setting shows beside its cost."""
    from matplotlib.ticker import LogLocator, NullFormatter, ScalarFormatter
    fig, axes = figure(8.0, 3.4, ncols=2)
    labelled = ~runs["split"].str.contains(r"_r[0-9]+$|^loto_", regex=True)
    for ax, col, xlabel in ((axes[0], "train_s", "training wall time (s, CPU)"),
                            (axes[1], "latency_ms", "inference latency per frame pair (ms, batch 1)")):
        for row, main in zip(runs.itertuples(), labelled):
            loto = row.split.startswith("loto_")
            ax.plot(getattr(row, col), row.mae, "x" if loto else "o", ms=6 if main else 4, alpha=1.0 if main else 0.5,
                    color=_colour(looks, row.variant, "#4C72B0"))
            if main:
                ax.annotate(row.run, (getattr(row, col), row.mae), fontsize=7, xytext=(3, 3), textcoords="offset points")
        pts = runs[labelled].sort_values(col)
        front = pts[pts["mae"] <= pts["mae"].cummin()]
        ax.step(front[col], front["mae"], where="post", color="grey", lw=1, ls="--", label="Pareto front (repeat 0)")
        ax.plot([], [], "o", color="0.5", ms=4, alpha=0.5, label="other repeats")
        ax.plot([], [], "x", color="0.5", label="leave-one-tool-out")
        ax.set_xscale("log")
        ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 1.5, 2.0, 3.0, 5.0, 7.0)))
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())      # plain numbers, a few per decade
        ax.set_xlabel(xlabel)
        ax.set_ylabel("test MAE (N)")
        ax.legend(fontsize=7)
    fig.suptitle("Error against run time: every run")
    save_figure(out, fig)
    close(fig)
    save_figure_data(out, runs)


BASELINE_LABELS = {"mean_predictor": "mean predictor", "tactile_rmse_linear": "tactile RMSE (own reference)",
                   "rest_frame_rmse_linear": "tactile RMSE (mean rest frame)",
                   "one_finger_rmse_linear": "tactile RMSE (one finger)"}


def interval_bars(scores: dict[str, dict[str, list[float]]], summary: dict[str, dict], label: str, out: Path, *, looks: dict[str, Variant]) -> None:
    """Variants and baselines over the repeated splits: mean with its 95 % interval, and each split's
    value as a dot; MAE and R² side by side."""
    names = list(scores)
    fig, axes = figure(8.5, 0.42 * len(names) + 1.4, ncols=2, sharey=True)
    y = np.arange(len(names))[::-1]
    for ax, m, title in ((axes[0], "mae", f"MAE of {label} force (N)"), (axes[1], "r2", "R²")):
        for yi, name in zip(y, names):
            s = summary[name][m]
            color = _colour(looks, name, "0.45")
            if np.isfinite(s["low"]):
                ax.plot([s["low"], s["high"]], [yi, yi], "-", lw=2.5, color=color, alpha=0.6)
            ax.plot(s["mean"], yi, "D", ms=6, color=color)
            ax.plot(scores[name][m], np.full(len(scores[name][m]), yi) + 0.18, ".", ms=4, color="k", alpha=0.6)
        ax.set_xlabel(title)
        if m == "r2":
            ax.set_xlim(max(-0.2, ax.get_xlim()[0]), 1.0)
    axes[0].set_yticks(y, [_label(looks, n, BASELINE_LABELS.get(n, n)) for n in names], fontsize=8)
    n = summary[names[0]]["mae"]["n"]
    fig.suptitle(f"Over {n} repeated trial splits: mean (◆), 95 % interval (bar), each split (•)")
    save_figure(out, fig)
    close(fig)
    save_figure_data(out, pd.DataFrame([{"model": name, "n": summary[name]["mae"]["n"],
                                         **{f"{m}_{k}": summary[name][m][k] for m in ("mae", "r2")
                                            for k in ("mean", "low", "high")}} for name in names]))


def loto_bars(loto: dict, label: str, out: Path, *, looks: dict[str, Variant]) -> None:
    """Full model, leave-one-tool-out: MAE and R² per held-out tool, with the mean over tools and its
    95 % interval as a band."""
    tools = list(loto["per_tool"])
    fig, axes = figure(7.5, 3.0, ncols=2)
    for ax, m, title in ((axes[0], "mae", f"MAE of {label} force (N)"), (axes[1], "r2", "R²")):
        ax.bar(range(len(tools)), [loto["per_tool"][t][m] for t in tools], color=_colour(looks, "full", "#4C72B0"), alpha=0.8)
        s = loto["over_tools"][m]
        ax.axhline(s["mean"], color="k", lw=1, label=f"mean {s['mean']:.3f}")
        if np.isfinite(s["low"]):
            ax.axhspan(s["low"], s["high"], color="0.5", alpha=0.2, label="95 % interval")
        ax.set_xticks(range(len(tools)), [t.replace("_", " ") for t in tools], fontsize=8)
        ax.set_ylabel(title)
        ax.legend(fontsize=7)
    axes[0].set_xlabel("held-out tool")
    axes[1].set_xlabel("held-out tool")
    fig.suptitle("Full model, each tool left out of training in turn")
    save_figure(out, fig)
    close(fig)
