"""A tiny tool-force dataset in the dataset stage's format, its trial split, and a short CPU
training configuration: what the trainer's tests train on."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.tool.data.loader import ToolFrames
from tactilepipe.tool.data.splits import label_stats
from tactilepipe.tool.model.train_config import TrainConfig

S = 32            # image size of the training tests (the smoke scale)
# torch threads of a test: under `make test` two pytest-xdist workers share the two cores, and a
# second thread per worker only oversubscribes them (a training test ran 8x slower beside the
# other worker); a lone pytest gets both
TORCH_THREADS = 1 if os.environ.get("PYTEST_XDIST_WORKER") else 2


def make_dataset(root: Path, n_trials: int = 8, per_trial: int = 20, size: int = S, seed: int = 0,
                 nan_at: int | None = None) -> Path:
    """A tiny dataset in the dataset stage's format: per trial a textured reference of each finger;
    each frame adds a Gaussian blob whose brightness grows with the force (left 1x, right 0.6x)."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:size, 0:size] / size
    refs = np.empty((n_trials, 2, size, size), np.uint8)
    frames = np.empty((n_trials * per_trial, 2, size, size), np.uint8)
    rows = []
    for t in range(n_trials):
        base = [60 + 40 * rng.random() * (xx + yy) + rng.normal(0, 3, (size, size)) for _ in range(2)]
        refs[t] = np.clip(np.stack(base), 0, 255)
        cx, cy = rng.uniform(0.3, 0.7, 2)
        blob = np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / 0.02)
        for k in range(per_trial):
            force = rng.uniform(2.0, 20.0)
            i = t * per_trial + k
            for s, gain in ((0, 1.0), (1, 0.6)):
                img = base[s] + gain * 7.0 * force * blob + rng.normal(0, 2, (size, size))
                frames[i, s] = np.clip(img, 0, 255)
            rows.append({"trial_index": t, "trial": f"trial{t:02d}", "tool": "screwdriver_1", "pose": "p0",
                         "normal": force, "shear": 0.1 * force})
    samples = pd.DataFrame(rows)
    if nan_at is not None:
        samples.loc[nan_at, "normal"] = np.nan
    root.mkdir(parents=True, exist_ok=True)
    np.save(root / "frames.npy", frames)
    np.save(root / "references.npy", refs)
    samples.to_parquet(root / "samples.parquet", index=False)
    return root


def make_split_dict(data: ToolFrames) -> dict:
    trial = data.trial_index
    train = np.flatnonzero(trial < 6)
    val = np.flatnonzero(trial == 6)
    test = np.flatnonzero(trial == 7)
    finite = train[np.isfinite(data.labels[train])]
    return {"name": "trial", "kind": "trial", "repeat": 0, "label": "normal", "train": train.tolist(), "validation": val.tolist(),
            "test": test.tolist(), "label_stats": label_stats(data.labels[finite])}


def quick_cfg(**kw) -> TrainConfig:
    """A small, fast training set-up; every field spelled out (TrainConfig has no defaults)."""
    base = dict(variant="full", depth=18, image_size=S, lr=2e-4, lr_schedule="constant", batch_size=24, max_epochs=3,
                patience=10000, normalise="minmax", seed=7, device="auto", amp=True, num_threads=TORCH_THREADS,
                max_train_batches_per_epoch=0, bn_recalibration_batches=20, gam_channel_gate="sigmoid",
                width=16, kernels="native")
    return TrainConfig(**{**base, **kw})
