"""Figures of a tool dataset (study 000, Fig. 4): where a figure of the data is drawn.

- pressing_strip: colour DIGIT frames of both fingers over one pressing cycle (contact,
  pressing, peak, lifting, restoration) above the force.
- rmse_vs_force: tactile RMSE of each finger against its reference frame, beside the force.
- force_profiles: one press of several tools and poses, with one force level marked.
- force_histogram: the label distribution (most frames at low force).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pandas as pd

from tactilepipe.core.atomic import save_figure
from tactilepipe.core.plotting import close, figure

PHASES = ("contact", "pressing", "peak", "lifting", "restoration")


def press_phases(t: np.ndarray, force: np.ndarray, contact_n: float = 0.5) -> dict[str, int]:
    """Sample index of each phase of the strongest press in a trial."""
    peak = int(np.argmax(force))
    before = np.flatnonzero(force[:peak] < contact_n)
    start = int(before[-1]) + 1 if len(before) else 0
    after = np.flatnonzero(force[peak:] < contact_n)
    end = peak + int(after[0]) if len(after) else len(force) - 1
    half = 0.5 * force[peak]
    rise = start + int(np.argmin(np.abs(force[start:peak + 1] - half)))
    fall = peak + int(np.argmin(np.abs(force[peak:end + 1] - half)))
    return {"contact": start, "pressing": rise, "peak": peak, "lifting": fall,
            "restoration": min(len(force) - 1, end + max(1, (end - start) // 4))}


def pressing_strip(images: dict[str, list[np.ndarray]], t: np.ndarray, force: np.ndarray, label: str,
                   title: str, out: Path) -> None:
    """images: {finger: [BGR frame at each phase]} in PHASES order; t, force: the trial's series."""
    phases = press_phases(t, force)
    fig, axes = figure(7.2, 6.0, nrows=3, ncols=5, gridspec_kw={"height_ratios": [1.3, 1.3, 1.0]})
    for r, (finger, frames) in enumerate(images.items()):
        for c, (phase, img) in enumerate(zip(PHASES, frames)):
            ax = axes[r, c]
            ax.imshow(cv2.cvtColor(img, cv2.COLOR_BGR2RGB))
            ax.set_xticks([]), ax.set_yticks([])
            ax.grid(False)
            if r == 0:
                ax.set_title(f"{phase}\n{force[phases[phase]]:.1f} N", fontsize=9)
            if c == 0:
                ax.set_ylabel(finger.replace("digit_", "") + " finger")
    gs = axes[2, 0].get_gridspec()
    for ax in axes[2]:
        ax.remove()
    ax = fig.add_subplot(gs[2, :])
    ax.plot(t, force, color="#C44E52", lw=1.2)
    for phase, k in phases.items():
        ax.axvline(t[k], color="k", lw=0.6, ls=":")
        ax.annotate(phase, (t[k], force.max()), fontsize=7, rotation=90, va="top", ha="right")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"{label} (N)")
    fig.suptitle(title)
    save_figure(out, fig)
    close(fig)


def tactile_rmse(frames: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Per-frame RMSE (grey levels) of frames (n, S, S) against a reference (S, S)."""
    diff = frames.astype(np.float32) - reference.astype(np.float32)
    return np.sqrt((diff ** 2).mean(axis=(1, 2)))


def rmse_vs_force(t: np.ndarray, rmse: np.ndarray, force: np.ndarray, label: str, title: str, out: Path) -> None:
    fig, ax = figure(6.4, 3.0)
    ax.plot(t, force, color="#C44E52", lw=1.2, label=f"{label} (Nano17)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"{label} (N)", color="#C44E52")
    ax2 = ax.twinx()
    ax2.grid(False)
    for k, (name, color) in enumerate((("left finger", "#4C72B0"), ("right finger", "#55A868"))):
        ax2.plot(t, rmse[:, k], color=color, lw=1.0, label=f"tactile RMSE, {name}")
    ax2.set_ylabel("tactile RMSE vs reference (grey levels)")
    lines = ax.get_legend_handles_labels()[0] + ax2.get_legend_handles_labels()[0]
    ax.legend(lines, [l.get_label() for l in lines], loc="upper left", frameon=True, framealpha=0.9)
    ax.set_title(title, fontsize=10)
    save_figure(out, fig)
    close(fig)


def force_profiles(samples: pd.DataFrame, label: str, level_n: float, out: Path, max_curves: int = 8) -> None:
    """The strongest press of one trial per (tool, pose), aligned at contact, with one force level
    marked: ``level_n``, or lower where needed so that the line crosses every curve shown."""
    fig, ax = figure(6.0, 3.4)
    shown, peaks = 0, []
    for (tool, pose), part in samples.groupby(["tool", "pose"], sort=True):
        trial = part["trial"].iloc[0]
        one = part[part["trial"] == trial]
        f, t = one[label].to_numpy(), one["t_s"].to_numpy()
        ph = press_phases(t, f)
        sel = slice(max(0, ph["contact"] - 3), ph["restoration"] + 1)
        ax.plot(t[sel] - t[ph["contact"]], f[sel], lw=1.2, label=pose.replace("@", " @ "))
        peaks.append(f[ph["peak"]])
        shown += 1
        if shown >= max_curves:
            break
    level_n = min(level_n, 0.8 * min(peaks)) if peaks else level_n
    ax.axhline(level_n, color="grey", lw=1.5, alpha=0.7)
    ax.annotate(f"{level_n:.1f} N", (ax.get_xlim()[1], level_n), ha="right", va="bottom", fontsize=8, color="grey")
    ax.set_xlabel("time since contact (s)")
    ax.set_ylabel(f"{label} (N)")
    ax.set_title("One loading cycle per tool and grasp pose: the same force, different imprints")
    ax.legend(fontsize=6.5, ncols=2)
    save_figure(out, fig)
    close(fig)


def force_histogram(labels: np.ndarray, label: str, out: Path) -> None:
    fig, ax = figure(4.5, 3.0)
    ax.hist(labels, bins=np.arange(np.floor(labels.min()), np.ceil(labels.max()) + 1, 1.0), color="#4C72B0")
    ax.set_yscale("log")
    ax.set_xlabel(f"{label} (N)")
    ax.set_ylabel("frame pairs (log)")
    ax.set_title(f"Label distribution ({len(labels)} frame pairs)")
    save_figure(out, fig)
    close(fig)
