"""Training data loader of a tool scene: where the decoded frames become tensors.

Frames were decoded once by the dataset stage into frames.npy / references.npy; here they are
memory-mapped, so a batch is one fancy-index read plus a type conversion (no image decoding).
A sample's input stacks, per finger, the current frame and that trial's reference frame:
channels [left, left_ref, right, right_ref], scaled to [0, 1].
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterator

import numpy as np
import pandas as pd

from tactilepipe.core.errors import ConfigError


class ToolFrames:
    def __init__(self, dataset_dir: str | Path, label: str):
        d = Path(dataset_dir)
        self.frames = np.load(d / "frames.npy", mmap_mode="r")
        self.references = np.load(d / "references.npy", mmap_mode="r")
        self.samples = pd.read_parquet(d / "samples.parquet")
        self.trial_index = self.samples["trial_index"].to_numpy()
        self.labels = self.samples[label].to_numpy(np.float32)
        self.orientation = _orientation(d / "qc.json")


    def __len__(self) -> int:
        return len(self.samples)

    def resized(self, size: int) -> "ToolFrames":
        """The same samples with every image area-downscaled to size x size (held in memory), for
        models trained on smaller inputs than the dataset was built with; never upsampled."""
        import copy
        import cv2
        stored = self.frames.shape[-1]
        if size == stored:
            return self
        if size > stored:
            raise ConfigError(f"a {size}-px model input from a data set of {stored}-px frames would be upsampled: "
                              f"tool_train.image_size must not exceed tool_ingest.stored_size")
        shrink = lambda a: np.stack([cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA)
                                     for img in a.reshape(-1, *a.shape[-2:])]).reshape(*a.shape[:-2], size, size)
        view = copy.copy(self)
        view.frames, view.references = shrink(np.asarray(self.frames)), shrink(np.asarray(self.references))
        return view

    def arrays(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Inputs (n, 4, S, S) uint8 and labels (n,) for sample indices ``idx``."""
        idx = np.asarray(idx)
        order = np.argsort(idx)                      # sorted reads are sequential on disk
        cur = self.frames[idx[order]]
        ref = self.references[self.trial_index[idx[order]]]
        x = np.empty((len(idx), 4) + cur.shape[2:], np.uint8)
        x[order, 0], x[order, 1], x[order, 2], x[order, 3] = cur[:, 0], ref[:, 0], cur[:, 1], ref[:, 1]
        return x, self.labels[idx]

    def batches(self, idx, batch_size: int, shuffle: bool, seed: int = 0) -> Iterator[tuple]:
        """Yield (x float32 torch tensor (b, 4, S, S) in [0, 1], y float32 tensor (b,), indices)."""
        import torch
        idx = np.asarray(idx)
        if shuffle:
            idx = np.random.default_rng(seed).permutation(idx)
        for start in range(0, len(idx), batch_size):
            part = idx[start:start + batch_size]
            x, y = self.arrays(part)
            yield torch.from_numpy(x).float().div_(255.0), torch.from_numpy(y), part


def _orientation(qc_path: Path) -> str | None:
    """portrait or landscape: how the recorded frames stood before the square resize (a dataset
    holds one; None for a dataset without qc.json)."""
    import json
    from tactilepipe.tool.data.dataset import orientation
    if not qc_path.is_file():
        return None
    kinds = {orientation(t) for t in json.loads(qc_path.read_text()).get("trials", [])}
    return kinds.pop() if len(kinds) == 1 else None
