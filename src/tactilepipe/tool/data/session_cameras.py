"""Each trial's cameras held against its session's: a finger recorded by the other finger's DIGIT.

Every DIGIT has a look of its own (its LEDs' gradient, its gel's blemishes, where the camera sits),
and the grasp changes only a band of the frame. So across a session, the first frames of
digit_left resemble each other more than they resemble digit_right's. A trial whose two folders
hold each other's recording (cables swapped, or folders renamed) resembles the session the other
way round: its labels are right, but a model that learns which finger is which would be fed the
fingers backwards (and the single-sensor variant the wrong one).
"""

from __future__ import annotations

import numpy as np

MIN_TRIALS = 3          # a session's look needs a few trials to be the majority's
# A trial's left-minus-right first frame, projected on the session's (1: the session's cameras,
# -1: swapped). The grasp differs between the fingers too: clean simulated trials, whose two
# DIGITs differ only by small shifts and gains, project at +0.04 to +0.93 (57 trials at 32 px).
SWAPPED_BELOW = -0.3


def swapped_cameras(first_frames: list[tuple[np.ndarray, np.ndarray]], sessions: list[str]) -> dict[int, str]:
    """Index -> why, for each trial whose left-minus-right first frame is the session's the other
    way round; the session's is the difference of its per-pixel medians."""
    out = {}
    for session in set(sessions):
        members = [i for i, s in enumerate(sessions) if s == session]
        if len(members) < MIN_TRIALS:
            continue
        left = np.median(np.stack([first_frames[i][0] for i in members]), axis=0).astype(np.float64)
        right = np.median(np.stack([first_frames[i][1] for i in members]), axis=0).astype(np.float64)
        pattern = (left - right).ravel()
        pattern -= pattern.mean()
        norm = float(pattern @ pattern)
        if norm == 0:
            continue
        for i in members:
            a, b = (np.asarray(f, np.float64) for f in first_frames[i])
            diff = (a - b).ravel()
            projection = float((diff - diff.mean()) @ pattern) / norm
            if projection < SWAPPED_BELOW:
                out[i] = (f"witness 'cameras': its digit_left minus digit_right frame is the session's the other way "
                          f"round (projection {projection:+.2f} on the median of {len(members)} trials; below "
                          f"{SWAPPED_BELOW:+.1f}): the two cameras' folders or cables are swapped")
    return out
