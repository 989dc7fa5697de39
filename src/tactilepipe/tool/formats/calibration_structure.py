"""The Nano17's calibration matrix judged against the sensor's structure, after its cells and
rows have been judged alone (tool/formats/native_layout.py, read_calibration).

Two facts hold for every Nano17 matrix, whatever its gauge layout (ATI's three beams, where a row
draws on two to five gauges, or the simulator's one gauge per axis), with the tool offset ATI folds
into its torque rows (its files' own 6.1 mm):

- Units belong to rows: a row is N (or N·mm) per volt of gauge signal. Scaled by the axis's rated
  range (±25, ±25, ±35 N, ±250 N·mm), every row reaches its rated range at a similar gauge signal:
  the gauges and their amplifiers are alike (ATI's files: within a factor of about 2 of each other;
  the simulator's: within 10%). A row whose largest cell makes it reach its range at 10x less (or
  more) signal than the others holds a cell off by 10x, a shifted decimal point.
- Transposed, the torque rows become the columns of gauges 4-6: per unit of rated
  range, the force rows then draw on gauges 4-6 about (250/25)² = 100x more than the torque rows
  on gauges 1-3; in a matrix the right way round the two are within a factor 5 (2,000 seeds of the
  simulator: at most 4.1, transposed at least 19; ATI's layout: about 1.4, transposed 30-70).

Not seen: a cell off by 10x that neither sets its row's scale nor crosses the blocks (a cross-talk
cell x10, or /10 of one of several similar cells of an ATI row): its labels move by a share of one
gauge's signal, not by 10x. Nor the Tz row's largest cell x10 where a tool offset of more than
about 6 mm was folded into the torque rows (they grow, Tz does not, and their spread hides it).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from tactilepipe.core.errors import InputError

AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
# the Nano17 SI-25-0.25's rated ranges (ATI): Fx, Fy ±25 N, Fz ±35 N, torques ±250 N·mm
RATED_RANGE = np.array([25.0, 25.0, 35.0, 250.0, 250.0, 250.0])
ROW_SCALE_FACTOR = 3.5       # a row's full-scale signal within this factor of the other rows' median
TRANSPOSED_RATIO = 9.0       # between a valid matrix's block ratio (<= ~4) and a transposed one's (>= ~19)
NEGLIGIBLE = 1e-3            # block means below this share of the rows' scale count as no evidence


def full_scale_volts(matrix: np.ndarray) -> np.ndarray:
    """Per row, the gauge signal (V) at which the row's largest cell alone reaches the rated range."""
    with np.errstate(divide="ignore"):
        return RATED_RANGE / np.abs(matrix).max(axis=1)


def block_ratio(matrix: np.ndarray) -> float:
    """Per unit of rated range: the force rows' mean cell on gauges 4-6 over the torque rows' mean
    cell on gauges 1-3, each block's largest cell left out (one bad cell does not move it)."""
    scaled = np.abs(matrix) / RATED_RANGE[:, None]
    upper = np.sort(scaled[:3, 3:].ravel())[:-1].mean()
    lower = np.sort(scaled[3:, :3].ravel())[:-1].mean()
    floor = NEGLIGIBLE * float(np.median(scaled.max(axis=1)))
    return float(upper / max(lower, floor)) if floor > 0 else 0.0


def check_structure(path: str | Path, matrix: np.ndarray) -> None:
    """InputError naming nano17.cal and the cause when the matrix (N and N·mm per volt) looks
    transposed, or one row's scale (its largest cell) is off from the other rows' by ~10x."""
    ratio = block_ratio(matrix)
    if ratio > TRANSPOSED_RATIO and block_ratio(matrix.T) <= TRANSPOSED_RATIO:
        raise InputError(path, f"the matrix looks transposed: per unit of rated range its force rows draw {ratio:.0f}x "
                               f"more on gauges 4-6 than its torque rows on gauges 1-3 (a Nano17's matrix: within "
                               f"{TRANSPOSED_RATIO:g}x; its transpose is); were its columns written as the UserAxis rows?")
    volts = full_scale_volts(matrix)
    for i in range(len(AXES)):
        others = float(np.median(np.delete(volts, i)))
        factor = others / volts[i]
        if 1 / ROW_SCALE_FACTOR <= factor <= ROW_SCALE_FACTOR:
            continue
        j = int(np.argmax(np.abs(matrix[i])))
        decades = round(math.log10(factor)) or int(math.copysign(1, math.log10(factor)))
        size = f"~{10 ** decades:g}x" if decades > 0 else f"~1/{10 ** -decades:g}"
        unit = "N" if AXES[i].startswith("F") else "N·mm"
        raise InputError(path, f"cell {AXES[i]},g{j + 1} ({matrix[i, j]:.6g} {unit}/V, the row's largest) is {size} "
                               f"({factor:.3g}x) its size in a Nano17: with it the {AXES[i]} row reaches the rated ±{RATED_RANGE[i]:g} "
                               f"{unit} at {volts[i]:.3g} V of gauge signal, the other rows at {others:.3g} V "
                               f"(median; a Nano17's rows agree within {ROW_SCALE_FACTOR:g}x): a shifted decimal point?",
                         f"UserAxis {AXES[i]}")
