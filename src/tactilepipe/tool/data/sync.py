"""Putting the force on the camera clock, and giving every frame pair its force.

The Arduino counts milliseconds from its own boot; the host only knows roughly when it opened
the port. The residual offset is found from what both sensors see (tool/data/clock_sync.py). Then
every frame pair gets the force linearly interpolated at its time, unless the nearest force
samples are further apart than ``max_gap_s`` (the frame is dropped and counted).
"""

from __future__ import annotations

import numpy as np



def interpolate_at(times: np.ndarray, sample_t: np.ndarray, values: np.ndarray, max_gap: float
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Values (n, k) linearly interpolated at ``times``; mask of times whose bracketing samples
    exist and lie at most ``max_gap`` apart."""
    idx = np.searchsorted(sample_t, times)
    inside = (idx > 0) & (idx < len(sample_t))
    left = sample_t[np.clip(idx - 1, 0, len(sample_t) - 1)]
    right = sample_t[np.clip(idx, 0, len(sample_t) - 1)]
    exact = np.isin(times, sample_t)
    ok = (inside & (right - left <= max_gap)) | exact
    out = np.column_stack([np.interp(times, sample_t, values[:, j]) for j in range(values.shape[1])])
    return out, ok


def pair_frames(left_ns: np.ndarray, right_ns: np.ndarray, tolerance_ns: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices (i_left, i_right) of frames taken within ``tolerance_ns`` of each other (each used once)."""
    j = np.clip(np.searchsorted(right_ns, left_ns), 1, max(1, len(right_ns) - 1))
    j = np.where(np.abs(right_ns[j - 1] - left_ns) <= np.abs(right_ns[np.minimum(j, len(right_ns) - 1)] - left_ns),
                 j - 1, np.minimum(j, len(right_ns) - 1))
    ok = np.abs(right_ns[j] - left_ns) <= tolerance_ns
    i_left, i_right = np.flatnonzero(ok), j[ok]
    _, first = np.unique(i_right, return_index=True)     # a right frame pairs with one left frame
    return i_left[first], i_right[first]
