"""Figures of the grasp-regime comparison: R² by modality per regime, and grip force vs volume."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.atomic import save_figure
from tactilepipe.plotting import close, figure
from tactilepipe.volume.figures import label

MODALITY_COLORS = {"fz": "#C44E52", "fy": "#4C72B0", "fy_fz": "#8172B2", "fx_fy_fz": "#55A868",
                   "baseline": "#999999"}


def r2_by_regime(table: pd.DataFrame, methods: list[str], out: Path) -> None:
    """One group of bars per regime (the paper's last), one bar per modality, ± std over folds.
    Bars below zero are cut at the axis and their value written at the bottom."""
    regimes = list(table["regime"])
    width = 0.8 / len(methods)
    fig, ax = figure(1.3 + 1.25 * len(regimes), 3.4)
    floor = -0.2
    for j, m in enumerate(methods):
        x = np.arange(len(regimes)) + (j - (len(methods) - 1) / 2) * width
        means = table[f"{m}_mean"].to_numpy(float)
        stds = table[f"{m}_std"].to_numpy(float)
        shown = np.clip(np.nan_to_num(means, nan=floor), floor, None)
        ax.bar(x, shown - floor, width, bottom=floor, yerr=np.where(means > floor, stds, 0), capsize=2,
               color=MODALITY_COLORS.get(m), label=label(m).replace("\n", " "), error_kw={"lw": 0.8})
        for xi, mean in zip(x, means):
            if not np.isfinite(mean) or mean < floor:
                ax.annotate("undef." if not np.isfinite(mean) else f"{mean:.2f}", (xi, floor), ha="center",
                            va="bottom", fontsize=6, rotation=90, xytext=(0, 2), textcoords="offset points")
    ax.axhline(0, color="k", lw=0.6)
    ax.set_xticks(np.arange(len(regimes)), regimes)
    ax.set_ylim(floor, 1.05)
    ax.set_ylabel("R² on test lifts (mean ± std over folds)")
    ax.set_title("Volume regression by input modality under each grasp regime")
    ax.legend(ncols=len(methods), fontsize=7, loc="lower center", bbox_to_anchor=(0.5, 1.08), frameon=False)
    save_figure(out, fig)
    close(fig)


def fz_vs_volume(qc: pd.DataFrame, out: Path) -> None:
    """Mean off-table Fz of every lift against its volume, one colour per regime: the rig
    measurement that separates the regimes (flat under force control)."""
    fig, ax = figure(4.8, 3.2)
    for regime, part in qc.groupby("regime", sort=False):
        jitter = (np.arange(len(part)) % 5 - 2) * 1.5
        points = ax.plot(part["volume_ml"] + jitter, part["mean_fz0"], "o", ms=2.5, alpha=0.5)
        means = part.groupby("volume_ml")["mean_fz0"].mean()
        ax.plot(means.index, means.to_numpy(), "-", color=points[0].get_color(), lw=1.4, label=regime)
    ax.set_xlabel("water volume (ml)")
    ax.set_ylabel("mean off-table Fz of sensor 0 (N)")
    ax.set_title("Grip (normal) force against volume")
    ax.legend(fontsize=8)
    save_figure(out, fig)
    close(fig)
