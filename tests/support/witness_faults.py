"""Faults of a real rig's force chain, injected into a native trial as the rig would have recorded
them: an ADC reference other than 5 V, a gauge amplifier's gain, a zero taken off true zero, rows
of nano17.cal swapped or negated, a cell of it x10, the whole of it transposed, frames.csv stamped at another rate. Each rewrites the trial's
own files (or its own session's nano17.cal), nothing else."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np

from tactilepipe.tool.formats import native_layout as layout

BIAS_WINDOW_S = 0.5            # the importer's zero-force window at the start of force.log


def _read_log(trial: Path) -> tuple[str, np.ndarray, np.ndarray]:
    lines = (trial / "force.log").read_text().splitlines()
    rows = np.array([[int(v) for v in ln.split(",")] for ln in lines[1:]], np.int64)
    return lines[0], rows[:, 0], rows[:, 1:]


def _write_log(trial: Path, header: str, ms: np.ndarray, counts: np.ndarray) -> None:
    counts = np.clip(np.round(counts), 1, layout.ADC_COUNTS - 1).astype(np.int64)
    body = [",".join(str(int(v)) for v in (t, *c)) for t, c in zip(ms, counts)]
    (trial / "force.log").write_text("\n".join([header, *body]) + "\n")


def adc_reference(trial: Path, volts: float) -> None:
    """The Arduino's ADC referenced to ``volts`` instead of 5 V: every count reads 5/volts times."""
    header, ms, counts = _read_log(trial)
    _write_log(trial, header, ms, counts * (layout.ADC_VOLTS / volts))


def gauge_gain(trial: Path, gain: float) -> None:
    """A gauge amplifier at ``gain`` times its calibrated gain: the counts' excursions from the
    unloaded level scale, the unloaded level does not (the ADC witness cannot see it)."""
    header, ms, counts = _read_log(trial)
    zero = counts[ms <= ms[0] + BIAS_WINDOW_S * 1000].mean(axis=0)
    _write_log(trial, header, ms, zero + gain * (counts - zero))


def zero_offset(trial: Path, calibration: np.ndarray, fz_n: float) -> None:
    """The zero-force window reads Fz = ``fz_n`` (a pull or a load while the zero was taken): every
    later reading is off by -fz_n on Fz (the normal label of an upright sensor by +fz_n)."""
    header, ms, counts = _read_log(trial)
    dv = np.linalg.solve(calibration, np.array([0.0, 0.0, fz_n, 0.0, 0.0, 0.0]))
    window = ms <= ms[0] + BIAS_WINDOW_S * 1000
    counts = counts.astype(np.float64)
    counts[window] += dv * layout.ADC_COUNTS / layout.ADC_VOLTS
    _write_log(trial, header, ms, counts)


def calibration_rows(session: Path, swap: tuple[str, str] | None = None, negate: str | None = None) -> np.ndarray:
    """Rewrite the session's nano17.cal with two rows' names swapped, or one row negated."""
    matrix = layout.read_calibration(session / "nano17.cal")
    if swap:
        a, b = (layout.AXES.index(n) for n in swap)
        matrix[[a, b]] = matrix[[b, a]]
    if negate:
        matrix[layout.AXES.index(negate)] *= -1
    layout.write_calibration(session / "nano17.cal", matrix)
    return matrix


def calibration_cell(session: Path, axis: str, factor: float) -> str:
    """Rewrite the session's nano17.cal with the row's largest cell times ``factor`` (a shifted
    decimal point); returns the cell's name, e.g. "Fz,g3"."""
    matrix = layout.read_calibration(session / "nano17.cal")
    i = layout.AXES.index(axis)
    j = int(np.argmax(np.abs(matrix[i])))
    matrix[i, j] *= factor
    layout.write_calibration(session / "nano17.cal", matrix)
    return f"{axis},g{j + 1}"


def calibration_transposed(session: Path) -> None:
    """Rewrite the session's nano17.cal transposed (rows read as columns when it was typed in)."""
    matrix = layout.read_calibration(session / "nano17.cal")
    layout.write_calibration(session / "nano17.cal", matrix.T.copy())


def frame_rate(trial: Path, factor: float, declare: bool = False) -> None:
    """frames.csv stamped as if taken ``factor`` times faster than they were (both fingers); with
    ``declare`` meta.json says the same rate (no declared-rate witness left to see it)."""
    for sensor in layout.SENSORS:
        stamps = layout.read_frame_index(trial / sensor)
        new = stamps[0] + np.round((stamps - stamps[0]) / factor).astype(np.int64)
        (trial / sensor / "frames.csv").write_text("frame,host_ns\n" + "".join(f"{i},{t}\n" for i, t in enumerate(new)))
    if declare:
        meta = json.loads((trial / "meta.json").read_text())
        meta["camera_fps"] = meta.get("camera_fps", 30.0) * factor
        (trial / "meta.json").write_text(json.dumps(meta))


def copy_trial(session: Path, trial: str, dest_session: Path) -> Path:
    """The trial and its session's nano17.cal, copied into ``dest_session`` (a session of its own, so
    a calibration fault touches only it)."""
    dest_session.mkdir(parents=True, exist_ok=True)
    shutil.copy2(session / "nano17.cal", dest_session / "nano17.cal")
    return Path(shutil.copytree(session / trial, dest_session / trial))
