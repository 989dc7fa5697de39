"""Are the two fingers' frames from two DIGITs? Judged on the decoded, preprocessed frames.

Opening a native trial already refuses one camera's files given for both fingers (the same stamps,
byte-identical files: tool/formats/native_import.py). What only the pixels show: one device path
given for both fingers at recording, so that each finger got every other frame of one camera
(different stamps, different bytes, the same view). Two DIGITs never show the same view: each
has its own gel, LEDs and lens, and the simulated fingers differ by 2-4 gray levels on average at
32 px, while one camera's consecutive frames differ by 0.15-1 (noise, and the press's change).
"""

from __future__ import annotations

import numpy as np

# the fingers' difference (each left frame against the right frame nearest in time) at most this
# many times a camera's own frame-to-frame difference: the same view, one camera
SAME_VIEW_RATIO = 2.5


def _mean_abs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per frame, the mean absolute gray-level difference of two stacks (n, h, w)."""
    return np.abs(a.astype(np.int16) - b.astype(np.int16)).mean(axis=(1, 2))


def one_camera_twice(frames: dict, grays: dict) -> str | None:
    """The cause, when the two fingers' frames show one camera's view; None for two cameras.

    ``frames``: sensor -> SensorFrames (host_ns), ``grays``: sensor -> (n, size, size) uint8, the
    frames as ingest preprocesses them (tool/data/ingest.py)."""
    if len(grays) != 2 or any(len(g) < 2 for g in grays.values()):
        return None
    (a, ga), (b, gb) = grays.items()
    ta, tb = frames[a].host_ns, frames[b].host_ns
    j = np.clip(np.searchsorted(tb, ta), 1, len(tb) - 1)
    j = np.where(np.abs(tb[j - 1] - ta) <= np.abs(tb[j] - ta), j - 1, j)      # the nearest in time
    across = float(np.median(_mean_abs(ga, gb[j])))
    within = max(float(np.median(_mean_abs(g[1:], g[:-1]))) for g in (ga, gb))
    if across > SAME_VIEW_RATIO * within and across > 0:
        return None
    return (f"{a} and {b} show one camera's view: their frames differ by {across:.2f} gray levels (median, each "
            f"against the other finger's nearest in time), no more than a camera's own consecutive frames "
            f"({within:.2f}; two DIGITs differ by several times that): one device given for both fingers?")
