"""Shared figure style: paper-sized, readable fonts, no display needed; a figure's data beside it."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

STYLE = {
    "figure.dpi": 100, "savefig.dpi": 200, "font.size": 10, "axes.titlesize": 11,
    "axes.labelsize": 10, "legend.fontsize": 8, "axes.grid": True, "grid.alpha": 0.3,
    "axes.spines.top": False, "axes.spines.right": False,
}


def figure(width: float = 4.5, height: float = 3.2, **kwargs):
    plt.rcParams.update(STYLE)
    return plt.subplots(figsize=(width, height), constrained_layout=True, **kwargs)


def close(fig) -> None:
    plt.close(fig)


def figure_data_path(png: str | Path) -> Path:
    """The table of the numbers a figure draws, beside it (<figure>.csv): a DVC data plot."""
    return Path(png).with_suffix(".csv")


def save_figure_data(png: str | Path, frame) -> None:
    """Write a figure's numbers (a DataFrame, one row per point) as CSV beside its PNG, so DVC can
    draw two revisions of them on one axis (`dvc plots diff`, dvc.yaml `plots:`)."""
    from tactilepipe.core.atomic import write_text
    write_text(figure_data_path(png), frame.to_csv(index=False))
