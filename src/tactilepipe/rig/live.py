"""`tactilepipe live`: the tool force estimated from the two DIGITs as they stream.

Each camera is read on its own thread (rig/cameras.py) and keeps only its newest frame. The
estimator pairs the newest frames of both fingers once they lie within half a frame period of
each other, and runs the trained model on the pair with the zero-force reference, exactly as
``predict`` does (tool/model/stream.py, PairEstimator). When the model is slower than the
cameras, the frames that were replaced before it could take them are skipped, counted per
camera and reported, never hidden.

The reference pair is the first pair delivered, taken with the fingers out of contact as the
study does (the command asks for that), or one saved by an earlier run (``--reference``). It is
saved beside the log as reference.npz.

The log (CSV): ``host_ns`` of the pair (the later capture), the frame numbers, the estimate in N,
``latency_ms`` from that capture to the estimate, and ``compute_ms`` (preprocessing + model).
Compare it with a recorded force by host time.
"""

from __future__ import annotations

import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tactilepipe.core.atomic import atomic_path
from tactilepipe.core.errors import InputError
from tactilepipe.rig.cameras import MODES, Camera

LOG_HEADER = "host_ns,left_frame,right_frame,estimate_n,latency_ms,compute_ms"


@dataclass
class _Newest:
    """The newest frame of one camera; frames replaced before they were taken are skipped."""
    index: int = -1
    host_ns: int = 0
    frame: np.ndarray | None = None
    taken: int = -1
    skipped: int = 0


@dataclass
class LiveSummary:
    pairs: int = 0
    skipped: dict = field(default_factory=dict)       # per camera: frames never estimated on
    median_latency_ms: float = float("nan")
    median_compute_ms: float = float("nan")
    sustained_pairs_per_s: float = 0.0
    stopped: str = ""
    not_a_force: bool = False                          # stopped on an estimate that is NaN or infinite


class _PairSource:
    def __init__(self, period_ns: int):
        self.period_ns = period_ns
        self.cond = threading.Condition()
        self.newest = {"digit_left": _Newest(), "digit_right": _Newest()}

    def put(self, sensor: str, index: int, host_ns: int, frame: np.ndarray) -> None:
        with self.cond:
            slot = self.newest[sensor]
            if slot.frame is not None and slot.taken != slot.index:
                slot.skipped += 1                      # replaced before the estimator took it
            slot.index, slot.host_ns, slot.frame = index, host_ns, frame
            self.cond.notify_all()

    def take(self, timeout_s: float):
        """The next pair of fresh frames within half a period of each other, or None on timeout."""
        deadline = time.monotonic() + timeout_s
        with self.cond:
            while True:
                left, right = self.newest["digit_left"], self.newest["digit_right"]
                fresh = left.frame is not None and right.frame is not None and \
                    left.taken != left.index and right.taken != right.index
                if fresh and abs(left.host_ns - right.host_ns) <= self.period_ns // 2:
                    left.taken, right.taken = left.index, right.index
                    return left.index, left.frame, right.index, right.frame, max(left.host_ns, right.host_ns)
                if fresh:                              # the older one waits for its partner's next frame
                    older = left if left.host_ns < right.host_ns else right
                    older.taken = older.index
                    older.skipped += 1
                    continue
                remaining = deadline - time.monotonic()
                if remaining <= 0 or not self.cond.wait(remaining):
                    return None


def run_live(checkpoint: Path, sources: tuple[str, str], mode: str, p: dict, seconds: float, log_path: Path,
             reference: Path | None = None, label_range=None, out=sys.stdout) -> LiveSummary:
    from tactilepipe.tool.model.stream import check_orientation, estimator
    period_ns = int(1e9 / MODES[mode][2])
    pairs = _PairSource(period_ns)
    with estimator(checkpoint, p, label_range) as est:
        est.warm_up()
        cameras = [Camera(s, src, mode, lambda i, t, f, s=s: pairs.put(s, i, t, f))
                   for s, src in zip(pairs.newest, sources)]
        for c in cameras:
            c.start()
        summary = LiveSummary()
        latencies, computes = [], []
        try:
            log_path.parent.mkdir(parents=True, exist_ok=True)
            with open(log_path, "w", buffering=1) as log:     # a log: kept line by line, also after Ctrl-C
                print(LOG_HEADER, file=log)
                first = _reference(pairs, reference, cameras, log_path.parent / "reference.npz")
                check_orientation(checkpoint, first[0], est.meta.get("frame_orientation"))
                est.set_reference(*first)
                print(f"# reference pair taken; estimating {est.meta.get('label') or 'force'} for {seconds:g} s",
                      file=out, flush=True)
                start = time.monotonic()
                while time.monotonic() - start < seconds:
                    try:
                        got = pairs.take(timeout_s=0.5)
                    except KeyboardInterrupt:
                        summary.stopped = "Ctrl-C"
                        break
                    if got is None:
                        lost = [f"{c.name}: {c.stats.lost}" for c in cameras if not c.running]
                        if lost:
                            summary.stopped = "; ".join(lost)
                            break
                        continue
                    i, left, j, right, host_ns = got
                    _check_sizes(first, left, right, (i, j), cameras, reference)
                    t0 = time.perf_counter()
                    value = est.estimate(left, right)
                    if not np.isfinite(value):     # never shown or logged as a force
                        summary.stopped = f"the model's estimate for frames {i}/{j} is {value}, not a force"
                        summary.not_a_force = True
                        break
                    compute = (time.perf_counter() - t0) * 1000
                    latency = (time.time_ns() - host_ns) / 1e6
                    latencies.append(latency)
                    computes.append(compute)
                    print(f"{host_ns},{i},{j},{value:.6f},{latency:.2f},{compute:.2f}", file=log)
                    print(f"{value:8.3f} N   latency {latency:6.1f} ms", file=out, flush=True)
                    last = time.monotonic()
                wall = (last if latencies else time.monotonic()) - start     # to the last estimate
        finally:
            for c in cameras:
                c.stop()
    summary.pairs = len(latencies)
    summary.skipped = {s: slot.skipped for s, slot in pairs.newest.items()}
    if latencies:
        summary.median_latency_ms = float(np.median(latencies))
        summary.median_compute_ms = float(np.median(computes))
        summary.sustained_pairs_per_s = summary.pairs / wall
    print(f"# {summary.pairs} pairs in {wall:.1f} s ({summary.sustained_pairs_per_s:.1f} pairs/s), median latency "
          f"{summary.median_latency_ms:.1f} ms (compute {summary.median_compute_ms:.1f} ms); frames skipped "
          f"{summary.skipped}" + (f"; stopped early: {summary.stopped}" if summary.stopped else ""), file=out)
    return summary


def _check_sizes(first, left, right, numbers, cameras: list[Camera], reference: Path | None) -> None:
    """InputError when a frame's size is not its reference frame's: a stream whose resolution
    changed mid-way, or a saved reference of another mode (the model would compare a frame with a
    reference of another view, and preprocessing would hide it)."""
    for camera, ref, frame, number in zip(cameras, first, (left, right), numbers):
        if frame.shape != ref.shape:
            size, was = f"{frame.shape[1]}x{frame.shape[0]}", f"{ref.shape[1]}x{ref.shape[0]}"
            where = f"its frames in {reference} are {was}" if reference else f"its reference frame was {was}: the " \
                                                                           f"resolution changed mid-stream"
            raise InputError(camera.source, f"{camera.name}: frame {number} is {size}, {where}")


def _valid_reference(path: Path, left, right):
    """The pair of a reference.npz, refused unless both are BGR uint8 frames of one size."""
    for name, frame in (("digit_left", left), ("digit_right", right)):
        if frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3:
            raise InputError(path, f"{name} is {frame.dtype} of shape {frame.shape}, not a BGR uint8 frame as "
                                   f"`tactilepipe live` saves it")
    if left.shape != right.shape:
        raise InputError(path, f"digit_left is {left.shape[1]}x{left.shape[0]}, digit_right "
                               f"{right.shape[1]}x{right.shape[0]}: one mode streams both")
    return left, right


def _reference(pairs: _PairSource, reference: Path | None, cameras: list[Camera], save_to: Path):
    """The zero-force reference pair: from ``reference`` (a reference.npz of an earlier run), or
    the first pair the cameras deliver (saved to ``save_to``)."""
    if reference is not None:
        try:
            with np.load(reference) as z:
                return _valid_reference(reference, z["digit_left"], z["digit_right"])
        except (OSError, KeyError, ValueError) as exc:
            raise InputError(reference, f"not a reference.npz written by `tactilepipe live` ({exc})") from None
    got = pairs.take(timeout_s=5.0)
    if got is None:
        state = "; ".join(f"{c.name} ({c.source}): {c.stats.frames} frames{', ' + c.stats.lost if c.stats.lost else ''}"
                          for c in cameras)
        raise InputError(save_to.parent, f"no frame pair from the cameras within 5 s for the reference ({state})")
    _, left, _, right, _ = got
    with atomic_path(save_to) as tmp, open(tmp, "wb") as f:
        np.savez(f, digit_left=left, digit_right=right)
    return left, right
