"""Finding the Arduino clock's offset from the images, robustly, and knowing when it cannot be found.

The rig's force log is only coarsely on the host clock (port-open time + Arduino ms, good to a
few tenths of a second). The residual offset is the lag at which the force magnitude |F| best
explains what both DIGITs see. Every label depends on it, so the estimate must survive the
glitches real cameras produce and say when it has nothing to go on:

- change signal per finger: mean |frame - reference|, the reference being the per-pixel median
  of the first REFERENCE_FRAMES frames (one bad first frame does not shift every value), then a
  running median over MEDIAN_FRAMES frames (a dimmed, near-black or torn frame, or two in a row,
  leaves no trace);
- score: correlation of that signal with |F|(t - d) over the overlap, for each lag d on a STEP_S
  grid within +-max_offset_s, per finger; the two fingers' curves are averaged. (A rank
  correlation was tried: it weighs the noise of the rest phases as much as the presses and
  put normal trials 30 ms off where this is within 5 ms; the running median already removes
  the outliers ranks would guard against.)
- lag: the best grid lag refined by a parabola through its neighbours (sub-frame);
- confidence: the peak score, and the agreement of the fingers: each finger's own best lag must
  lie within ``max_finger_disagreement_s`` of the other's (two cameras seeing the same presses
  agree; where they do not, the peak was found in noise). Otherwise the trial is refused, or
  keeps its coarse host clock with a warning counted in QC (``on_low_score``). A peak on the edge of the search
  window is always refused: the true offset may lie beyond it.
- a flat force log (|F| varies less than ``min_force_range_n``) and a frozen camera (every frame
  bit-identical: a real sensor's noise never repeats an exposure) leave nothing to align and are
  errors naming the file.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import median_filter

REFERENCE_FRAMES = 5     # frames whose per-pixel median is the change signal's reference
MEDIAN_FRAMES = 5        # running median width: removes runs of up to 2 bad frames
STEP_S = 0.005           # lag grid (s); a frame period is 33 ms, the parabola refines below the step
CURVE_DECIMALS = 3       # the score curve kept in the shard (for the QC figure)


@dataclass
class ClockFit:
    shift_s: float               # add to the coarse force times to put them on the camera clock
    score: float                 # peak correlation (mean of the fingers' curves)
    finger_shift_s: dict         # best lag of each finger alone (s)
    lags_s: np.ndarray           # the grid of lags tried
    curve: np.ndarray            # mean score at each lag
    on_edge: bool                # the peak is at the first or last lag of the window

    def record(self) -> dict:
        """What goes into the shard's clock record (JSON): the fit and its curve."""
        return {"refined_shift_s": float(self.shift_s), "xcorr": float(self.score),
                "finger_shift_s": {k: round(float(v), 4) for k, v in self.finger_shift_s.items()},
                "curve": {"lag0_s": float(self.lags_s[0]), "step_s": STEP_S,
                          "score": [round(float(s), CURVE_DECIMALS) for s in self.curve]}}


def change_signal(frames: np.ndarray) -> np.ndarray:
    """Per-frame tactile change (n,) of one finger's preprocessed frames (n, S, S), despiked."""
    frames = np.asarray(frames, np.float32)
    ref = np.median(frames[:REFERENCE_FRAMES], axis=0)
    raw = np.abs(frames - ref).mean(axis=(1, 2))
    if len(raw) < MEDIAN_FRAMES:
        return raw
    return median_filter(raw, size=MEDIAN_FRAMES, mode="mirror")


def _standardise(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, np.float64)
    std = x.std()
    return (x - x.mean()) / std if std > 0 else x * 0.0


def score_curve(frame_s: np.ndarray, change: np.ndarray, force_s: np.ndarray, force_mag: np.ndarray,
                lags_s: np.ndarray) -> np.ndarray:
    """Correlation of ``change`` (at the frame times) with |F| moved by each lag.

    Only frames whose shifted time lies inside the force log take part at a given lag, so an
    offset near the window's edge is scored on the overlap instead of on extrapolated force.
    """
    out = np.full(len(lags_s), np.nan)
    for k, d in enumerate(lags_s):
        inside = (frame_s - d >= force_s[0]) & (frame_s - d <= force_s[-1])
        if inside.sum() < MEDIAN_FRAMES * 2:
            continue
        f = np.interp(frame_s[inside] - d, force_s, force_mag)
        out[k] = np.mean(_standardise(change[inside]) * _standardise(f))
    return out


def _peak(lags_s: np.ndarray, curve: np.ndarray) -> tuple[float, int]:
    filled = np.where(np.isfinite(curve), curve, -np.inf)
    k = int(np.argmax(filled))
    d = float(lags_s[k])
    if 0 < k < len(curve) - 1 and np.isfinite(filled[k - 1]) and np.isfinite(filled[k + 1]):
        y0, y1, y2 = filled[k - 1:k + 2]
        denom = y0 - 2 * y1 + y2
        if denom < 0:
            d += 0.5 * (y0 - y2) / denom * STEP_S
    return d, k


def fit_offset(fingers: dict[str, tuple[np.ndarray, np.ndarray]], force_s: np.ndarray, force_mag: np.ndarray,
               search_s: float) -> ClockFit:
    """Offset of the force clock against the camera clock from each finger's (frame times (s),
    change signal); times on a common host clock, the true offset within +-search_s."""
    n_steps = int(round(search_s / STEP_S))
    lags = np.arange(-n_steps, n_steps + 1) * STEP_S
    curves = {name: score_curve(t, c, force_s, force_mag, lags) for name, (t, c) in fingers.items()}
    stack = np.stack(list(curves.values())) if curves else np.full((1, len(lags)), np.nan)
    seen = np.isfinite(stack).sum(axis=0)
    mean = np.where(seen > 0, np.nansum(stack, axis=0) / np.maximum(seen, 1), np.nan)
    if not np.isfinite(mean).any():
        return ClockFit(0.0, float("nan"), {}, lags, mean, False)
    shift, k = _peak(lags, mean)
    finger = {name: _peak(lags, c)[0] for name, c in curves.items() if np.isfinite(c).any()}
    valid = np.flatnonzero(np.isfinite(mean))
    return ClockFit(shift, float(mean[k]), finger, lags, mean, k in (valid[0], valid[-1]))


def frozen_frames(frames: np.ndarray) -> np.ndarray:
    """Mask (n,) of frames bit-identical to the one before (a stalled camera re-delivers a buffer)."""
    frames = np.asarray(frames)
    same = np.zeros(len(frames), bool)
    if len(frames) > 1:
        same[1:] = (frames[1:] == frames[:-1]).reshape(len(frames) - 1, -1).all(axis=1)
    return same


def frozen_runs(same: np.ndarray, min_run: int) -> list[tuple[int, int]]:
    """[first, last] frame of every run of at least ``min_run`` bit-identical frames."""
    runs, start = [], None
    for i, s in enumerate(np.append(same, False)):
        if s and start is None:
            start = i - 1
        elif not s and start is not None:
            if i - start >= min_run:
                runs.append((start, i - 1))
            start = None
    return runs


def judge(fit: ClockFit, clock: dict, search_s: float) -> str | None:
    """Why the fit cannot be trusted (None when it can). An edge peak is not judged here: it is
    always refused (the true offset may lie outside the window)."""
    if not np.isfinite(fit.score):
        return "the frames and the force log do not overlap at any lag"
    if fit.score < clock["min_score"]:
        return f"correlation {fit.score:.2f} < tool_ingest.clock.min_score {clock['min_score']}"
    lags = list(fit.finger_shift_s.values())
    if len(lags) == 2 and abs(lags[0] - lags[1]) > clock["max_finger_disagreement_s"]:
        return (f"the fingers' best lags ({', '.join(f'{k} {v:+.3f} s' for k, v in fit.finger_shift_s.items())}) "
                f"differ by more than tool_ingest.clock.max_finger_disagreement_s "
                f"{clock['max_finger_disagreement_s']} s")
    return None
