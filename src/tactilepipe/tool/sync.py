"""Putting the force on the camera clock, and giving every frame pair its force.

The Arduino counts milliseconds from its own boot; the host only knows roughly when it opened
the port. The residual offset is found by cross-correlating what both sensors see: the tactile
change against the reference frame (images) and the force magnitude (Nano17). Then every frame
pair gets the force linearly interpolated at its time, unless the nearest force samples are
further apart than ``max_gap_s`` (the frame is dropped and counted).
"""

from __future__ import annotations

import numpy as np

from tactilepipe.tool.layout import counts_to_volts


def calibrate(counts: np.ndarray, matrix: np.ndarray, bias_counts: np.ndarray) -> np.ndarray:
    """Forces/torques (n, 6) from gauge counts: F = C (v - v_bias)."""
    volts = counts_to_volts(counts) - counts_to_volts(bias_counts)
    return volts @ matrix.T


def _standardise(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, np.float64)
    std = x.std()
    return (x - x.mean()) / std if std > 0 else x * 0.0


def estimate_offset(frame_s: np.ndarray, tactile: np.ndarray, force_s: np.ndarray, force: np.ndarray,
                    search_s: float, step_s: float = 0.005) -> tuple[float, float]:
    """Shift d (s) that best aligns force(t - d) with the tactile signal, and its correlation.

    frame_s, force_s: times on their own clocks, already coarsely aligned (|true d| <= search_s).
    """
    lo = max(frame_s[0], force_s[0] + search_s)
    hi = min(frame_s[-1], force_s[-1] - search_s)
    if hi - lo < 4 * search_s:
        lo, hi = frame_s[0], frame_s[-1]
    grid = np.arange(lo, hi, step_s)
    a = _standardise(np.interp(grid, frame_s, tactile))
    shifts = np.arange(-search_s, search_s + step_s / 2, step_s)
    scores = np.array([np.mean(a * _standardise(np.interp(grid - d, force_s, force))) for d in shifts])
    k = int(np.argmax(scores))
    d = shifts[k]
    if 0 < k < len(scores) - 1:        # parabolic refinement between grid steps
        y0, y1, y2 = scores[k - 1:k + 2]
        denom = y0 - 2 * y1 + y2
        if denom < 0:
            d += 0.5 * (y0 - y2) / denom * step_s
    return float(d), float(scores[k])


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
