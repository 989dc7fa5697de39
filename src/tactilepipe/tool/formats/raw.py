"""RawTrial: one recorded trial as every importer hands it to ingest, whatever the source format.

Importers (native rig layout, the public dataset layout of study 000, ROS1/ROS2 bags) differ in
how frames and forces are stored and timed; after import they all look like this, on one clock
(host nanoseconds), and ingest never needs to know where a trial came from.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

SENSORS = ("digit_left", "digit_right")


@dataclass
class SensorFrames:
    """Frames of one DIGIT: host_ns per frame and a loader for the i-th frame kept (BGR uint8,
    H x W x 3). i counts the frames present, not the camera's numbers: where the camera dropped
    frames (native frames.csv skipping numbers) frame i is the camera's ``numbers[i]``."""
    host_ns: np.ndarray
    load: Callable[[int], np.ndarray]
    source: list[str]                    # file (and record) of each frame, for error messages
    numbers: np.ndarray | None = None    # the camera's frame number of each (None: 0..n-1)

    def number(self, i: int) -> int:
        """The camera's number of the i-th frame kept (what a message about it should say)."""
        return int(self.numbers[i]) if self.numbers is not None else int(i)

    def __len__(self) -> int:
        return len(self.host_ns)


@dataclass
class RawTrial:
    trial: str                           # unique within the dataset, e.g. "<session>/<trial>"
    tool: str
    kind: str                            # "normal" or "shear"
    orientation_deg: float
    insertion_mm: float
    frames: dict[str, SensorFrames]      # keys: SENSORS (one key for a single-sensor recording)
    force_host_ns: np.ndarray            # (m,) force sample times on the host clock
    force_n: np.ndarray                  # (m, 3) Fx, Fy, Fz at the tool tip, N
    clock: dict = field(default_factory=dict)   # how force times were put on the host clock
    drops: dict = field(default_factory=dict)   # counted drops while importing (reason -> count)
    source: str = ""                     # path of the recording
    reference: dict = field(default_factory=dict)  # sensor -> BGR zero-force reference frame, where the
                                         # format fixes one apart from the frames (public layout: frame 0,
                                         # kept even when its own label was dropped); else the first pair
    evidence: dict = field(default_factory=dict)   # facts outside the force chain the format records (native:
                                         # unloaded ADC counts, declared rates, recorder): tool/data/witness.py
