"""Figures of study 001 (volume): R² bars, mu-R² curves, true vs estimated volume, pillar map."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.colors import LinearSegmentedColormap, Normalize
from matplotlib.patches import Circle

from tactilepipe.core.atomic import save_figure
from tactilepipe.papillarray.messages import PILLAR_ROWCOL
from tactilepipe.core.plotting import close, figure, save_figure_data

LABELS = {"fx_fy_fz": "{Fx,Fy,Fz}", "fy_fz": "{Fy,Fz}", "fy": "Fy", "fz": "Fz", "baseline": "est_vol\n(baseline)"}


def label(method: str) -> str:
    return LABELS.get(method, method)


def r2_bars(r2: dict, out: Path) -> None:
    methods = list(r2)
    means = [r2[m]["mean"] for m in methods]
    # error bars: the 95 % interval of the mean (none drawn where it is undefined)
    low = [m_ - r2[m]["ci95"][0] if np.isfinite(r2[m]["ci95"][0]) else 0.0 for m, m_ in zip(methods, means)]
    high = [r2[m]["ci95"][1] - m_ if np.isfinite(r2[m]["ci95"][1]) else 0.0 for m, m_ in zip(methods, means)]
    fig, ax = figure(4.8, 3.2)
    colors = ["#4C72B0" if m != "baseline" else "#999999" for m in methods]
    bars = ax.bar(range(len(methods)), means, yerr=[low, high], capsize=4, color=colors)
    for bar, mean in zip(bars, means):
        ax.annotate(f"{mean:.3f}", (bar.get_x() + bar.get_width() / 2, max(mean, 0)), ha="center",
                    va="bottom", fontsize=8, xytext=(0, 3), textcoords="offset points")
    ax.set_xticks(range(len(methods)), [label(m) for m in methods])
    ax.set_ylabel("R² on test lifts (mean, 95 % interval)")
    ax.set_ylim(min(0.0, min(means) - 0.1), 1.08)
    ax.set_title("Volume regression by input modality")
    save_figure(out, fig)
    close(fig)


def mu_curves(curve: pd.DataFrame, optima: pd.DataFrame, mu_star: float, out: Path,
              warning: str | None = None) -> None:
    """mu-R² curve per training fold with its optimum (a ring when on the sweep's edge) and mu*."""
    fig, ax = figure(4.8, 3.2)
    for fold, part in curve.groupby("fold"):
        line, = ax.plot(part["mu"], part["r2_train"], lw=1.2, label=f"d{fold + 1} train")
        opt = optima[optima["fold"] == fold].iloc[0]
        edge = bool(opt.get("on_edge", False))
        ax.plot(opt["mu_opt"], opt["r2_train"], "o", color=line.get_color(), ms=7 if edge else 4,
                mfc="none" if edge else line.get_color())
    if np.isfinite(mu_star):
        ax.axvline(mu_star, color="k", ls="--", lw=1, label=f"μ* = {mu_star:.3f}")
    if warning:
        ax.text(0.02, 0.02, f"⚠ {warning}", transform=ax.transAxes, fontsize=8, color="#b30000")
    ax.set_xlabel("friction coefficient μ")
    ax.set_ylabel("R² of est_vol on the training fold")
    ax.set_title("Algebraic baseline: μ sweep per training fold")
    ax.legend(ncols=2)
    save_figure(out, fig)
    close(fig)
    # one row per mu: the folds' mean, lowest and highest R² (one line each in `dvc plots diff`)
    r2 = curve.groupby("mu")["r2_train"]
    save_figure_data(out, pd.DataFrame({"mu": r2.mean().index, "r2_train_mean": r2.mean().to_numpy(),
                                        "r2_train_min": r2.min().to_numpy(), "r2_train_max": r2.max().to_numpy()}))


def true_vs_estimated(per_lift: pd.DataFrame, method: str, out: Path) -> None:
    """per_lift: set, volume_ml, pred_ml (one row per lift and fold)."""
    fig, ax = figure(4.5, 3.6)
    main = per_lift[per_lift["set"] == "test"]
    classes = sorted(main["volume_ml"].unique())
    ax.boxplot([main.loc[main["volume_ml"] == v, "pred_ml"] for v in classes], positions=classes,
               widths=18, manage_ticks=False, patch_artist=True,
               boxprops={"facecolor": "#c6d4ea"}, medianprops={"color": "#1f3d7a"})
    unseen = per_lift[per_lift["set"] == "unseen"]
    if len(unseen):
        for v in sorted(unseen["volume_ml"].unique()):
            vals = unseen.loc[unseen["volume_ml"] == v, "pred_ml"]
            ax.errorbar(v, vals.mean(), yerr=vals.std(), fmt="D", color="#C44E52", capsize=3,
                        label="unseen volumes" if v == unseen["volume_ml"].min() else None)
    lims = [min(classes) - 25, max(classes) + 25]
    ax.plot(lims, lims, "k--", lw=0.8, label="ideal")
    ax.set_xlim(lims)
    ax.set_xlabel("true volume (ml)")
    ax.set_ylabel("estimated volume per lift (ml)")
    ax.set_title(f"MLP {label(method)}: test lifts, all folds")
    ax.legend(loc="upper left")
    save_figure(out, fig)
    close(fig)


def runtime_scatter(table: pd.DataFrame, out: Path) -> None:
    fig, ax = figure(4.5, 3.2)
    for row in table.itertuples():
        ax.errorbar(row.fit_s, row.r2_mean, yerr=row.r2_std, fmt="o", capsize=3)
        ax.annotate(label(row.method).replace("\n", " "), (row.fit_s, row.r2_mean), fontsize=8,
                    xytext=(4, -10), textcoords="offset points")
    ax.set_xscale("log")
    ax.set_xlabel("fit wall time per fold (s, log)")
    ax.set_ylabel("test R²")
    ax.set_title("Error against run time")
    save_figure(out, fig)
    close(fig)


PINK_RED = LinearSegmentedColormap.from_list("pink_red", ["#fde0e6", "#f08080", "#b30000", "#5c0000"])


def pillar_map(forces: np.ndarray, title: str, out: Path) -> None:
    """forces: (2, 9, 3) pillar forces of both sensors at one instant, drawn as the paper's interface.

    Each pillar is a circle coloured by fZ (light pink to dark red; negative fZ, i.e. noise, grey)
    with an arrow for (fX, fY).
    """
    fmax = max(float(forces[..., 2].max()), 1e-6)
    norm = Normalize(0.0, fmax)
    shear_max = max(float(np.linalg.norm(forces[..., :2], axis=-1).max()), 1e-6)
    fig, axes = figure(6.4, 3.4, ncols=2)
    for s, ax in enumerate(axes):
        for i, (row, col) in enumerate(PILLAR_ROWCOL):
            x, y = col, 2 - row
            fz = forces[s, i, 2]
            face = "#bdbdbd" if fz < 0 else PINK_RED(norm(fz))
            ax.add_patch(Circle((x, y), 0.38, facecolor=face, edgecolor="k", lw=0.8))
            fx, fy = forces[s, i, 0], forces[s, i, 1]
            # y of the sensor points down the pad, so the arrow is drawn with -fY upwards
            ax.arrow(x, y, 0.45 * fx / shear_max, -0.45 * fy / shear_max, width=0.03,
                     color="#1f3d7a", length_includes_head=True, head_width=0.12)
            ax.text(x, y - 0.52, f"{fz:.2f}", ha="center", va="top", fontsize=7)
        ax.set_xlim(-0.6, 2.6)
        ax.set_ylim(-0.75, 2.55)
        ax.set_aspect("equal")
        ax.axis("off")
        ax.set_title(f"sensor {s}: Fz {forces[s, :, 2].sum():.2f} N, Fy {forces[s, :, 1].sum():.2f} N")
    sm = __import__("matplotlib").cm.ScalarMappable(norm=norm, cmap=PINK_RED)
    fig.colorbar(sm, ax=axes, shrink=0.8, label="pillar fZ (N)")
    fig.suptitle(title)
    save_figure(out, fig)
    close(fig)
