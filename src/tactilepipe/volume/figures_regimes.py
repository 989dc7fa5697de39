"""Figures of the grasp-regime comparison: R² by modality per regime, and grip force vs volume."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.core.atomic import save_figure
from tactilepipe.core.plotting import close, figure
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


LINE_STYLES = ["-", "--", ":", "-."]
PHASES = [("fz_before_lift", "on the table, before lift-off"), ("fz_held", "held off the table"),
          ("fz_after_place", "on the table, after set-down")]


def fz_vs_volume(qc: pd.DataFrame, sensor: int, out: Path) -> None:
    """Mean Fz of every lift against its volume in the three phases, one colour per regime: the
    rig measurement that separates the regimes (flat in all three under force control)."""
    fig, axes = figure(9.6, 3.2, ncols=len(PHASES), sharey=True)
    for ax, (column, title) in zip(axes, PHASES):
        for k, (regime, part) in enumerate(qc.groupby("regime", sort=False)):
            color = f"C{k}"
            jitter = (np.arange(len(part)) % 5 - 2) * 1.5
            ax.plot(part["volume_ml"] + jitter, part[column], "o", ms=2, alpha=0.4, color=color)
            means = part.groupby("volume_ml")[column].mean()
            # regimes that agree draw the same curve: line styles keep each visible
            ax.plot(means.index, means.to_numpy(), LINE_STYLES[k % len(LINE_STYLES)], color=color, lw=1.4,
                    label=regime)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("water volume (ml)")
    axes[0].set_ylabel(f"mean Fz of sensor {sensor} per lift (N)")
    axes[0].legend(fontsize=7)
    fig.suptitle("Grip (normal) force against volume, gripper closed at the same setting", fontsize=10)
    save_figure(out, fig)
    close(fig)
