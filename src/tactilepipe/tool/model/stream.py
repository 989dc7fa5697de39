"""`tactilepipe predict`: stream a recorded trial through a trained model, pair by pair.

Each frame pair is preprocessed exactly as for training (tool/ingest.preprocess at the ingest size,
then the loader's area downscale to the model's input size), stacked with
the trial's first pair as the zero-force reference, and run at batch 1; the prediction and the
latency (preprocessing + model) are printed per pair, then a summary with the sustained rate.

Threads (params.yaml ``predict``): batch-1 inference of a small model is latency-bound, and on a
CPU shared with other jobs a thread per core spinning between ops loses its core to them at
every op; one passive thread keeps the DIGIT rate where two spinning ones collapsed
(benchmarks/bench_predict_load.py).
"""

from __future__ import annotations

import os
import sys
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

from tactilepipe.core.errors import ConfigError, InputError
from tactilepipe.tool.formats.trials import open_trial
from tactilepipe.tool.data.ingest import preprocess
from tactilepipe.tool.data.sync import pair_frames


class PairEstimator:
    """A trained model applied to one frame pair at a time, exactly as in training: each frame
    through ingest's preprocessing at the dataset size, then the loader's area downscale to the
    model's input size (ToolFrames.resized), stacked with the zero-force reference pair."""

    def __init__(self, model, meta: dict, ingest_size: int):
        import torch
        from tactilepipe.tool.model.train import denormalise
        self._torch, self._denormalise = torch, denormalise
        self.model, self.meta, self.ingest_size = model.eval(), meta, ingest_size
        self.size = meta["image_size"]
        self.reference: list[np.ndarray] | None = None

    def prep(self, bgr: np.ndarray) -> np.ndarray:
        img = preprocess(bgr, self.ingest_size)
        return img if self.ingest_size == self.size else cv2.resize(img, (self.size, self.size),
                                                                    interpolation=cv2.INTER_AREA)

    def warm_up(self, passes: int = 3) -> None:
        """Run the model a few times on a blank input: the first passes allocate and pick kernels, and
        would otherwise delay the first frames of a live stream."""
        x = self._torch.zeros(1, 4, self.size, self.size)
        with self._torch.no_grad():
            for _ in range(passes):
                self.model(x)

    def set_reference(self, left_bgr: np.ndarray, right_bgr: np.ndarray) -> None:
        self.reference = [self.prep(left_bgr), self.prep(right_bgr)]

    def estimate(self, left_bgr: np.ndarray, right_bgr: np.ndarray) -> float:
        """The force (N) for one frame pair (BGR, the layout's orientation)."""
        ref = self.reference
        x = np.stack([self.prep(left_bgr), ref[0], self.prep(right_bgr), ref[1]])[None].astype(np.float32) / 255.0
        with self._torch.no_grad():
            y = self.model(self._torch.from_numpy(x)).reshape(-1).numpy()
        return float(np.asarray(self._denormalise(y, self.meta["label_stats"], self.meta["normalise"])).reshape(-1)[0])


def prepare_process(p: dict) -> None:
    """The process settings of params.yaml ``predict`` that OpenMP, MKL and ATen read when torch
    first loads: its wait policy and the kernels. Effective when a command calls this before torch
    is imported (the CLI does); a later call keeps native kernels, and refuses portable ones that
    are not in force."""
    from tactilepipe.tool.checks import kernels_conflict
    from tactilepipe.tool.model.kernels import use_kernels
    os.environ["OMP_WAIT_POLICY"] = p["predict"]["wait_policy"].upper()
    if why := kernels_conflict("predict", p["predict"]["kernels"], p["predict"]["num_threads"]):
        raise ConfigError(why)
    use_kernels(p["predict"]["kernels"])


@contextmanager
def estimator(checkpoint: Path, p: dict, label_range=None) -> Iterator[PairEstimator]:
    """A PairEstimator of ``checkpoint`` on the threads and kernels of params.yaml ``predict``
    (the caller's thread count is restored after).

    A checkpoint of the public code (best_model_*.pth) runs at the ingest size; its normal-force
    outputs need ``label_range`` (min, max in N), which it does not record."""
    prepare_process(p)
    import torch
    from tactilepipe.tool.model.inference import load_model
    from tactilepipe.tool.model.kernels import require_active
    saved_threads = torch.get_num_threads()
    torch.set_num_threads(p["predict"]["num_threads"])
    try:
        require_active(p["predict"]["kernels"])
        model, meta = load_model(checkpoint, image_size=p["tool_ingest"]["stored_size"])
        if meta["label_stats"] is None:                # a public-code checkpoint
            meta = {**meta, "label_stats": _public_label_stats(checkpoint, meta, label_range)}
        yield PairEstimator(model, meta, p["tool_ingest"]["stored_size"])
    finally:
        torch.set_num_threads(saved_threads)       # an in-process caller keeps its own setting


def stream_predictions(checkpoint: Path, trial: Path, fmt: str, p: dict, limit: int | None = None,
                       out=sys.stdout, label_range=None) -> dict:
    with estimator(checkpoint, p, label_range) as est:
        return _stream(est, trial, fmt, p, limit, out)


def _public_label_stats(checkpoint: Path, meta: dict, label_range) -> dict:
    if meta["head"] == "shear":
        return {"min": 0.0, "max": 1.0}                 # its shear head predicts N
    if label_range is None:
        raise InputError(checkpoint, "a public-code normal-force checkpoint predicts force scaled to its data set's "
                                     "range: give it with --label-range MIN_N MAX_N")
    return {"min": float(label_range[0]), "max": float(label_range[1])}


def _stream(est: PairEstimator, trial, fmt, p, limit, out) -> dict:
    raw = open_trial(trial, fmt, p["tool_ingest"]["ros_topics"])
    left, right = raw.frames["digit_left"], raw.frames["digit_right"]
    period = float(np.median(np.diff(left.host_ns))) if len(left) > 1 else 1e9 / 30
    il, ir = pair_frames(left.host_ns, right.host_ns, int(period / 2))
    if len(il) == 0:
        raise InputError(trial, f"no frame pair: no digit_left frame lies within half a frame period of a "
                                f"digit_right frame (digit_left {_span(left.host_ns)}, digit_right "
                                f"{_span(right.host_ns)}): are both cameras on the host clock?")
    check_orientation(trial, left.load(int(il[0])), est.meta.get("frame_orientation"))
    if limit:
        il, ir = il[:limit], ir[:limit]
    # the zero-force reference: the format's own (public layout: frame 0), else the first pair
    if {"digit_left", "digit_right"} <= set(raw.reference):
        est.set_reference(raw.reference["digit_left"], raw.reference["digit_right"])
    else:
        est.set_reference(left.load(int(il[0])), right.load(int(ir[0])))
    latencies, preds = [], []
    print("pair,left_frame,right_frame,t_s,prediction_n,latency_ms", file=out)
    t_start = time.perf_counter()
    for k, (i, j) in enumerate(zip(il, ir)):
        t0 = time.perf_counter()
        pred = est.estimate(left.load(int(i)), right.load(int(j)))
        if not np.isfinite(pred):          # finite weights can still overflow: never print it as a force
            raise InputError(trial, f"frame pair {k} (left frame {i}, right frame {j}): the model's estimate is {pred}, "
                                    f"not a force; {k} pair(s) before it were estimated")
        latencies.append((time.perf_counter() - t0) * 1000)
        preds.append(pred)
        t_s = (left.host_ns[i] - left.host_ns[il[0]]) / 1e9
        print(f"{k},{i},{j},{t_s:.3f},{pred:.6f},{latencies[-1]:.2f}", file=out)
    wall = time.perf_counter() - t_start
    summary = {"pairs": len(preds), "median_latency_ms": float(np.median(latencies)),
               "sustained_pairs_per_s": len(preds) / wall}
    print(f"# {summary['pairs']} frame pairs, median latency {summary['median_latency_ms']:.1f} ms, "
          f"sustained {summary['sustained_pairs_per_s']:.1f} pairs/s (decode + preprocess + model), "
          f"{p['predict']['kernels']} kernels", file=out)
    return summary


def _span(host_ns: np.ndarray) -> str:
    return f"{host_ns[0] / 1e9:.3f}-{host_ns[-1] / 1e9:.3f} s" if len(host_ns) else "no frames"


def check_orientation(trial: Path, bgr: np.ndarray, trained: str | None) -> None:
    """Frames standing the other way than the model's training frames put the contact elsewhere
    after the square resize: refused (a checkpoint that does not record it is not checked)."""
    from tactilepipe.tool.formats.native_layout import frame_orientation
    h, w = bgr.shape[:2]
    here = frame_orientation(w, h)
    if trained in ("portrait", "landscape", "square") and here != trained:
        raise InputError(trial, f"frames are {here} ({w}x{h}), the model was trained on {trained} frames: rotate "
                                f"them to {trained} first")
