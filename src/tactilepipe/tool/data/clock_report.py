"""QC figure of a session's clock alignment: each native trial's correlation against lag, the lag
chosen marked, from the score curves ingest stores in the shards (tool/data/clock_sync.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tactilepipe.core.atomic import save_figure
from tactilepipe.tool.data.ingest import read_shard_info


def clock_figure(shards: list[Path], out_png: Path, title: str = "") -> int:
    """Plot every shard that holds a clock curve (public and ROS trials have none); returns how
    many were plotted. Trials that kept the host clock are drawn dashed."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8, 4.5))
    n = 0
    for shard in shards:
        info = read_shard_info(shard)
        clock = info.get("clock", {})
        curve = clock.get("curve")
        if not curve:
            continue
        score = np.asarray(curve["score"], float)
        lags = curve["lag0_s"] + curve["step_s"] * np.arange(len(score))
        style = "--" if clock.get("fallback") else "-"
        line, = ax.plot(lags, score, style, lw=0.8, alpha=0.7)
        if not clock.get("fallback"):
            ax.plot([clock["refined_shift_s"]], [clock["xcorr"]], "o", ms=3, color=line.get_color())
        n += 1
    ax.set_xlabel("lag of the force clock (s)")
    ax.set_ylabel("correlation: tactile change vs |F|")
    ax.set_title(title or f"clock alignment, {n} trials (dot: lag chosen; dashed: host clock kept)")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(out_png, fig, dpi=120)
    plt.close(fig)
    return n
