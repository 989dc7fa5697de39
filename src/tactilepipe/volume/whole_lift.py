"""A bag is one whole lift: the container on the table at its first message, lifted once, put
down by its last message.

The off-table phase (dataset.off_table_segment) is the longest one in the bag and its load is
measured above the level at the bag's start. So a bag that starts with the container already held
has no zero to measure from (its load reads as nothing, or as too little), a second lift in the
same bag would be dropped unmentioned, and a bag that stops while the container is still held has
no put-down. Each is refused here with its cause named, never kept with a volume label:

- **starts after lift-off**: the vertical shear |Fy0| + |Fy1| over the bag's first samples (where
  the rest level is read) rises clearly (10 x the noise) above its level over the last ones, where
  the container stands on the table again. At its start the pads hold nothing but their bias (the
  gripper open, or just closed), so any clear load there is the container's weight. A bag that
  starts less than those samples (2 x ``segment.force_smooth_s``) before the pads take the load is
  refused the same way: its rest level would hold part of the load.
- **ends before the put-down**: the pads still carry half the lift's load or more over the last
  samples. Half, not 10 x the noise: a container set down with the gripper still closed may keep
  part of its weight on the pads as friction shear.
- **two lifts**: besides the lift's off-table phase, another phase long enough to be a lift on
  its own (``segment.min_off_table_s``) that carries at least half the lift's load. By the pose
  method, the arm raised again (an arm that rises after letting go carries nothing, and passes);
  by the force method, the load above half the lift's for that long, after dropping below it (a
  re-grip in the air that keeps more than half the weight is one phase; a bump shorter than
  ``min_off_table_s`` is none).
"""

from __future__ import annotations

import numpy as np

from tactilepipe.core.errors import InputError

CLEAR_NOISE = 10            # x the rest noise: a level clearly above it (as off_table_segment's)
SECOND_LIFT_SHARE = 0.5     # of the lift's load: a second phase carrying this much lifts the container
STILL_CARRIED_SHARE = 0.5   # of the lift's load: the pads still carry this much at the bag's end


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of every run of True values, in order."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))


def fill_short_gaps(mask: np.ndarray, max_gap: int) -> np.ndarray:
    """Set runs of False no longer than ``max_gap`` that lie between True samples."""
    out = mask.copy()
    edges = np.diff(np.concatenate([[1], mask.astype(np.int8), [1]]))
    starts, stops = np.flatnonzero(edges == -1), np.flatnonzero(edges == 1)
    for a, b in zip(starts, stops):
        if 0 < a and b < len(mask) and b - a <= max_gap:
            out[a:b] = True
    return out


def _ends(rec: dict, width: int) -> dict:
    """The vertical shear |Fy0| + |Fy1| over the bag's first and last 2 x ``width`` samples, where
    dataset._vertical_load reads the rest level: its median at each end (``first``, ``last``), the
    highest ``width``-sample mean among the first ones (``first_peak``: a load rising there), the
    noise of such a mean over the last ones (as _vertical_load's), and how long (s) they last."""
    fy = np.abs(np.nan_to_num(rec["fy0"])) + np.abs(np.nan_to_num(rec["fy1"]))
    n = max(2, 2 * width)
    first, last = fy[:n], fy[-n:]
    means = np.convolve(first, np.ones(width) / width, mode="valid") if len(first) >= width else first
    return {"first": float(np.median(first)), "first_peak": float(means.max()) if len(means) else 0.0,
            "last": float(np.median(last)), "last_noise": float(np.std(last) / np.sqrt(width)),
            "span": min(n, len(fy)) * (float(np.median(np.diff(rec["t"]))) if len(fy) > 1 else 0.0)}


def check_starts_on_table(rec: dict, width: int, path) -> None:
    """InputError when the bag's first samples already carry the container (see the module
    docstring); called before the off-table phase is looked for, which would miss it. Against the
    noise over the last samples (on the table): at the start a rising load is no noise."""
    ends = _ends(rec, width)
    excess, noise = ends["first_peak"] - ends["last"], ends["last_noise"]
    if excess > CLEAR_NOISE * noise:
        raise InputError(path, f"the bag starts after lift-off: the sensors already carry up to "
                               f"{ends['first_peak']:.3f} N of vertical shear (|Fy0| + |Fy1|) over its first "
                               f"{ends['span']:.2f} s, where its rest level is read, {excess:.3f} N more than over its "
                               f"last, on the table (clearly: 10 x the noise {noise:.3f} N there). A bag holds one "
                               f"whole lift: start recording with the container on the table")


def check_one_lift(rec: dict, seg: dict, load: np.ndarray, lifted: np.ndarray, used: str, start: int, stop: int,
                   width: int, path) -> None:
    """InputError when the bag holds a second lift besides [start, stop), or ends before the
    container is put down (see the module docstring). ``load``: the smoothed vertical shear above
    rest; ``lifted``: the method's off-table mask (its pose mask by the pose method)."""
    t = rec["t"]
    carried = float(np.median(load[start:stop]))
    if used == "force":
        lifted = fill_short_gaps(load >= SECOND_LIFT_SHARE * carried, 2 * width)
    others = [(a, b) for a, b in runs(lifted) if (b <= start or a >= stop)
              and t[b - 1] - t[a] >= seg["min_off_table_s"]
              and np.median(load[a:b]) >= SECOND_LIFT_SHARE * carried]
    if others:
        phases = sorted([(start, stop), others[0]])
        spans = " and ".join(f"{t[a]:.2f}-{t[b - 1]:.2f} s" for a, b in phases)
        loads = " and ".join(f"{float(np.median(load[a:b])):.3f} N" for a, b in phases)
        raise InputError(path, f"two lifts in one bag: off the table at {spans} (by the {used} method, the pads "
                               f"carrying {loads}). A bag holds one lift: record each lift in its own bag")
    ends = _ends(rec, width)
    still = ends["last"] - ends["first"]
    if still >= STILL_CARRIED_SHARE * carried:
        raise InputError(path, f"the bag ends before the container is put down: over its last {ends['span']:.2f} s "
                               f"the sensors still carry {still:.3f} N of vertical shear above their level over its "
                               f"first, of the {carried:.3f} N carried off the table from {t[start]:.2f} s. A bag "
                               f"holds one whole lift: stop recording once the container stands on the table")
