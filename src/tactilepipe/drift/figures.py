"""Figure of the drift scene: drift since the bias request per run, fitted curves, tolerance."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no display; must precede the pyplot import

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from tactilepipe.core import plotting  # noqa: E402  (the project's shared figure style)
from tactilepipe.core.atomic import save_figure  # noqa: E402

RUN_STYLE = {"unloaded": {"color": "#1f77b4", "marker": "o", "label": "unloaded: reading, mean ± SD"},
             "loaded": {"color": "#d62728", "marker": "s", "label": "loaded: error on the weight, mean ± SD"}}


def plot_drift_curves(series: pd.DataFrame, fits, tolerance_n: float):
    """Points ±1 SD within each recording, best-model curves (others faint), tolerance and the
    recalibration time of each run. ``fits`` is an ``analyse.DriftFits``."""
    fig, ax = plotting.figure(9.0, 4.6)
    for run, part in series.groupby("run", sort=False):
        style = RUN_STYLE.get(run, {"color": "0.3", "marker": "^", "label": run})
        t = part["t_min"].to_numpy(float)
        ax.errorbar(t, part["drift_n"], yerr=part["deviation_std_n"], fmt=style["marker"],
                    color=style["color"], capsize=3, ms=6, label=style["label"], zorder=3)
        if run == "loaded":
            # the loaded run's weight-off parts: offset drift only, no span drift
            ax.plot(t, part["baseline_drift_n"], style["marker"], mfc="none", color=style["color"],
                    ms=6, label="loaded run, weight off (baseline)", zorder=3)
        grid = np.linspace(0.0, t.max(), 300)
        best = fits.best_model.get(run)
        for name, model in fits.models.get(run, {}).items():
            if name == best:
                continue
            ax.plot(grid, model.predict(grid), color=style["color"], lw=0.8, ls=":", alpha=0.6)
        if best is not None:
            row = fits.table[(fits.table["run"] == run) & (fits.table["model"] == best)].iloc[0]
            ax.plot(grid, fits.models[run][best].predict(grid), color=style["color"], lw=2,
                    label=f"{run}: best fit {best} (LOO R² {row.loo_r2:.2f})")
        minutes = fits.recalibration_interval_min.get(run)
        if minutes is not None:
            ax.axvline(minutes, color=style["color"], ls="-.", lw=1,
                       label=f"{run}: recalibrate within {minutes:.1f} min")
    ax.plot([], [], color="0.4", lw=0.8, ls=":", label="other fitted models")
    ax.axhline(tolerance_n, color="0.2", ls="--", lw=1.2, label=f"tolerance {tolerance_n:g} N")
    ax.axhline(0.0, color="0.6", lw=0.6)
    ax.set_xlabel("Time since bias request (min)")
    ax.set_ylabel("Drift of global $F_z$ since t = 0 (N)")
    ax.set_title("PapillArray thermal drift: reading error vs. time")
    handles, labels = ax.get_legend_handles_labels()
    by_run = sorted(range(len(labels)), key=lambda i: (_legend_rank(labels[i]), i))
    ax.legend([handles[i] for i in by_run], [labels[i] for i in by_run], loc="upper left",
              bbox_to_anchor=(1.02, 1.0), frameon=False)  # outside the axes: never hides data
    return fig


def _legend_rank(label: str) -> int:
    """Legend grouped by run (its data first, then its fit), shared lines last."""
    data = [style["label"] for style in RUN_STYLE.values()]
    for rank, run in enumerate(RUN_STYLE):
        if label.startswith(run):
            return 2 * rank + (0 if label in data or "weight off" in label else 1)
    return 2 * len(RUN_STYLE)


def drift_curves_data(series: pd.DataFrame) -> pd.DataFrame:
    """The figure's points, one row per recording time: <run>_drift_n for every run (both runs of
    RUN_STYLE always, empty where a run has no recording at that time)."""
    runs = list(RUN_STYLE) + [r for r in series["run"].unique() if r not in RUN_STYLE]
    wide = series.pivot_table(index="t_min", columns="run", values="drift_n", aggfunc="mean").reindex(columns=runs)
    wide.columns = [f"{run}_drift_n" for run in wide.columns]
    return wide.reset_index()


def write_drift_figure(target: str | Path, series: pd.DataFrame, fits, tolerance_n: float) -> None:
    fig = plot_drift_curves(series, fits, tolerance_n)
    try:
        save_figure(target, fig)
    finally:
        plotting.close(fig)
    plotting.save_figure_data(target, drift_curves_data(series))
