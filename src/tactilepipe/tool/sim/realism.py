"""Do simulated tactile frames look like real ones? Side-by-side image statistics of two folders.

``tactilepipe realism REAL_DIR SIM_DIR`` (docs/digit_rendering.md) reads every JPEG / PNG under
each folder (recursively), turns landscape frames to portrait and brings every frame to the
first real frame's size, then reports per folder:

- channel mean (DN, B, G, R) over all frames;
- spatial std (DN): the std over each frame's pixels, averaged over frames;
- noise (DN): std of a frame minus its Gaussian blur (sigma 3 px), averaged over frames;
- layout: the folder's mean frame averaged onto a grid of 6 columns x 8 rows (portrait), per
  channel with the channel's mean removed; the Pearson correlation of the two folders' grids;
- change on contact: every frame against its reference (the first frame, in name order, of its
  own sub-folder, or a reference frame given for the folder): the mean absolute change (DN over
  pixels and channels), its 99th percentile over pixels (largest channel change of each pixel),
  and the share of pixels that changed by more than ``CHANGED_DN`` in some channel, as quantiles
  over frames.

A figure shows a montage of frames from both folders and histograms of pixel values and changes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from tactilepipe.core.errors import InputError
from tactilepipe.tool.sim.background import to_portrait
from tactilepipe.tool.formats.imagefile import read_image

EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp")
NOISE_SIGMA = 3.0               # px: what a frame's Gaussian blur keeps is not noise
GRID = (6, 8)                   # columns x rows of the layout grid (portrait)
CHANGED_DN = 10.0               # DN: a pixel changed on contact when some channel moved this much
QUANTILES = (0.1, 0.5, 0.9)


@dataclass
class FolderStats:
    """Statistics of one folder of frames."""
    folder: str
    n_frames: int
    size: tuple[int, int]                           # (width, height) the frames were compared at
    channel_mean: np.ndarray                        # (3,) B, G, R
    spatial_std: np.ndarray                         # (3,)
    noise_std: np.ndarray                           # (3,)
    layout: np.ndarray                              # (rows, cols, 3), channel means removed
    change_mean_dn: np.ndarray = field(default_factory=lambda: np.zeros(0))   # per frame with a reference
    change_share: np.ndarray = field(default_factory=lambda: np.zeros(0))
    change_p99: np.ndarray = field(default_factory=lambda: np.zeros(0))      # per frame: 99th percentile of |d|
    pixels: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))     # a sample, for the histograms
    changes: np.ndarray = field(default_factory=lambda: np.zeros(0))         # a sample of |change| (DN)
    examples: list = field(default_factory=list)    # a few frames for the montage


def frame_files(folder: str | Path) -> list[Path]:
    """Every frame file under ``folder`` (recursive, name order); InputError when there is none."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(folder, "not a folder of frames")
    files = sorted(p for p in folder.rglob("*") if p.is_file() and p.suffix.lower() in EXTENSIONS)
    if not files:
        raise InputError(folder, f"no frames ({', '.join(EXTENSIONS)}) in this folder or below it")
    return files


def read_frame(path: Path, size: tuple[int, int] | None) -> np.ndarray:
    """One frame as portrait float32 BGR, resized to ``size`` (width, height) when given."""
    img = read_image(path, cv2.IMREAD_COLOR)
    img = to_portrait(img)
    if size is not None and (img.shape[1], img.shape[0]) != size:
        interp = cv2.INTER_AREA if img.shape[1] > size[0] else cv2.INTER_LINEAR
        img = cv2.resize(img, size, interpolation=interp)
    return img.astype(np.float32)


def _layout(mean_frame: np.ndarray) -> np.ndarray:
    grid = cv2.resize(mean_frame, GRID, interpolation=cv2.INTER_AREA)
    return grid - grid.reshape(-1, 3).mean(axis=0)


def folder_stats(folder: str | Path, size: tuple[int, int] | None = None, reference: str | Path | None = None,
                 max_frames: int = 2000, seed: int = 0) -> FolderStats:
    """Statistics of the frames under ``folder`` (at most ``max_frames``, evenly spaced).

    size: (width, height) to compare at (None: the first frame's). reference: one frame every
    frame is compared with for the change statistic (None: the first frame of each sub-folder).
    """
    files = frame_files(folder)
    firsts: dict[Path, Path] = {}
    for path in files:                            # each sub-folder's reference, before any thinning
        firsts.setdefault(path.parent, path)
    if len(files) > max_frames:
        files = [files[i] for i in np.linspace(0, len(files) - 1, max_frames).round().astype(int)]
    rng = np.random.default_rng(seed)
    first = read_frame(files[0], size)
    size = (first.shape[1], first.shape[0])
    ref_fixed = read_frame(Path(reference), size) if reference else None
    total = np.zeros_like(first, dtype=np.float64)
    means, stds, noises, ch_mean, ch_share, ch_p99, pixels, changes, examples = [], [], [], [], [], [], [], [], []
    refs: dict[Path, np.ndarray] = {}
    for i, path in enumerate(files):
        img = first if i == 0 else read_frame(path, size)
        total += img
        flat = img.reshape(-1, 3)
        means.append(flat.mean(axis=0))
        stds.append(flat.std(axis=0))
        noises.append((img - cv2.GaussianBlur(img, (0, 0), NOISE_SIGMA)).reshape(-1, 3).std(axis=0))
        pixels.append(flat[rng.integers(0, len(flat), 200)])
        if ref_fixed is not None:
            ref = ref_fixed
        elif path == firsts[path.parent]:
            ref = None                            # a sub-folder's own reference: no change to report
        else:
            if path.parent not in refs:
                refs[path.parent] = read_frame(firsts[path.parent], size)
            ref = refs[path.parent]
        if ref is not None:
            diff = np.abs(img - ref)
            ch_mean.append(float(diff.mean()))
            ch_share.append(float((diff.max(axis=2) > CHANGED_DN).mean()))
            ch_p99.append(float(np.percentile(diff.max(axis=2), 99)))
            changes.append(diff.reshape(-1)[rng.integers(0, diff.size, 300)])
        if len(examples) < 4 and (i % max(1, len(files) // 4) == 0):
            examples.append(img.astype(np.uint8))
    return FolderStats(folder=str(folder), n_frames=len(files), size=size,
                       channel_mean=np.mean(means, axis=0), spatial_std=np.mean(stds, axis=0),
                       noise_std=np.mean(noises, axis=0), layout=_layout((total / len(files)).astype(np.float32)),
                       change_mean_dn=np.asarray(ch_mean), change_share=np.asarray(ch_share),
                       change_p99=np.asarray(ch_p99),
                       pixels=np.concatenate(pixels), changes=np.concatenate(changes) if changes else np.zeros(0),
                       examples=examples)


def layout_correlation(a: FolderStats, b: FolderStats) -> float:
    """Pearson correlation of two folders' low-frequency colour layouts (all channels)."""
    x, y = a.layout.reshape(-1), b.layout.reshape(-1)
    return float(np.corrcoef(x, y)[0, 1])


def compare(real_dir: str | Path, sim_dir: str | Path, real_ref: str | Path | None = None,
            sim_ref: str | Path | None = None, max_frames: int = 2000) -> dict:
    """Statistics of both folders (the simulated frames at the real ones' size) and their layout
    correlation; the dict ``report`` prints and ``figure`` draws."""
    real = folder_stats(real_dir, None, real_ref, max_frames)
    sim = folder_stats(sim_dir, real.size, sim_ref, max_frames)
    return {"real": real, "sim": sim, "layout_correlation": layout_correlation(real, sim)}


def _triple(v: np.ndarray, fmt: str = "{:.1f}") -> str:
    return " / ".join(fmt.format(x) for x in v)


def _quantiles(v: np.ndarray, fmt: str) -> str:
    if v.size == 0:
        return "-"
    return " / ".join(fmt.format(x) for x in np.quantile(v, QUANTILES))


def report(result: dict) -> str:
    """The side-by-side table (plain text)."""
    real, sim = result["real"], result["sim"]
    q = "/".join(f"p{int(x * 100)}" for x in QUANTILES)
    rows = [
        ("statistic", "real", "simulated"),
        ("frames", str(real.n_frames), str(sim.n_frames)),
        ("compared at (w x h)", f"{real.size[0]}x{real.size[1]}", f"{sim.size[0]}x{sim.size[1]}"),
        ("channel mean B / G / R (DN)", _triple(real.channel_mean), _triple(sim.channel_mean)),
        ("spatial std B / G / R (DN)", _triple(real.spatial_std), _triple(sim.spatial_std)),
        (f"noise std B / G / R (DN, minus blur s{NOISE_SIGMA:g})", _triple(real.noise_std, "{:.2f}"),
         _triple(sim.noise_std, "{:.2f}")),
        (f"layout correlation ({GRID[0]}x{GRID[1]} grid)", "1", f"{result['layout_correlation']:.3f}"),
        ("frames with a reference", str(real.change_mean_dn.size), str(sim.change_mean_dn.size)),
        (f"change mean |d| (DN) {q}", _quantiles(real.change_mean_dn, "{:.2f}"),
         _quantiles(sim.change_mean_dn, "{:.2f}")),
        (f"change p99 of |d| (DN) {q}", _quantiles(real.change_p99, "{:.1f}"), _quantiles(sim.change_p99, "{:.1f}")),
        (f"pixels changed > {CHANGED_DN:g} DN (%) {q}", _quantiles(100 * real.change_share, "{:.1f}"),
         _quantiles(100 * sim.change_share, "{:.1f}")),
    ]
    w0 = max(len(r[0]) for r in rows)
    w1 = max(len(r[1]) for r in rows)
    lines = [f"{a:<{w0}}  {b:<{w1}}  {c}" for a, b, c in rows]
    lines.insert(1, "-" * len(lines[0]))
    return "\n".join(lines) + "\n"


def figure(result: dict, path: str | Path) -> None:
    """Montage (real frames on top, simulated below) and histograms of pixel values and changes."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from tactilepipe.core.atomic import save_figure

    real, sim = result["real"], result["sim"]
    n = max(len(real.examples), len(sim.examples))
    fig = plt.figure(figsize=(2.0 * max(n, 4), 8.5))
    gs = fig.add_gridspec(3, max(n, 4), height_ratios=[1.3, 1.3, 1.0])
    for row, stats in enumerate((real, sim)):
        for j, img in enumerate(stats.examples):
            ax = fig.add_subplot(gs[row, j])
            ax.imshow(img[..., ::-1])
            ax.set_xticks([]), ax.set_yticks([])
            if j == 0:
                ax.set_ylabel("real" if row == 0 else "simulated")
    half = max(n, 4) // 2
    ax = fig.add_subplot(gs[2, :half])
    bins = np.arange(0, 257, 4)
    for c, colour in enumerate(("tab:blue", "tab:green", "tab:red")):
        ax.hist(real.pixels[:, c], bins, histtype="step", color=colour, density=True, label="real" if c == 0 else None)
        ax.hist(sim.pixels[:, c], bins, histtype="step", color=colour, density=True, linestyle="--",
                label="simulated" if c == 0 else None)
    ax.set_xlabel("pixel value (DN), B / G / R")
    ax.legend(fontsize=8)
    ax = fig.add_subplot(gs[2, half:])
    bins = np.linspace(0, 60, 61)
    for stats, style, label in ((real, "-", "real"), (sim, "--", "simulated")):
        if stats.changes.size:
            ax.hist(stats.changes, bins, histtype="step", linestyle=style, density=True, log=True, label=label)
    ax.set_xlabel("|frame - reference| (DN)")
    ax.legend(fontsize=8)
    fig.suptitle(f"layout correlation {result['layout_correlation']:.2f}")
    fig.tight_layout()
    save_figure(path, fig, dpi=90)
    plt.close(fig)
