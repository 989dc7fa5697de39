"""Per-recording readings of the drift study: one shard's global Fz split into its unloaded and
loaded parts, their means and spreads, and the deviation from what is really on the sensor
(what "deviation" means: drift/analyse.py); and the whole session's series of them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.core.errors import InputError
from tactilepipe.drift import RUNS, parse_recording_name

G = 9.81

def _read_fz(path: Path, sensor: int) -> tuple[np.ndarray, np.ndarray]:
    if not path.exists():
        raise InputError(path, "shard not found")
    try:
        frame = pd.read_parquet(path, columns=["stamp_ns", "sensor", "gfz"])
    except Exception as exc:  # pyarrow raises several types for damaged or foreign files
        raise InputError(path, f"cannot read shard (needs columns stamp_ns, sensor, gfz): "
                               f"{type(exc).__name__}: {exc}") from None
    frame = frame[frame["sensor"] == sensor].sort_values("stamp_ns")
    if len(frame) < 10:
        raise InputError(path, f"only {len(frame)} samples of sensor {sensor}: not a drift recording")
    t = (frame["stamp_ns"].to_numpy(np.int64) - int(frame["stamp_ns"].iloc[0])) / 1e9
    return t, frame["gfz"].to_numpy(np.float64)


def _interior(mask: np.ndarray, guard: int) -> np.ndarray:
    """Samples of ``mask`` at least ``guard`` samples away from a change of state (ramps excluded).

    The ends of the recording are not changes of state, so they are not trimmed.
    """
    if guard <= 0:
        return mask.copy()
    padded = np.pad(mask.astype(int), guard, mode="edge")
    window = np.convolve(padded, np.ones(2 * guard + 1, int), mode="valid")
    return window == 2 * guard + 1


def split_load(t: np.ndarray, fz: np.ndarray, smooth_s: float = 0.1, guard_s: float = 0.3
               ) -> tuple[np.ndarray, np.ndarray, float]:
    """(loaded samples, unloaded samples, step in N) of one recording, from global Fz alone.

    The smoothed trace is split halfway between its lowest and highest level; samples within
    ``guard_s`` of a crossing (placing or lifting the weight) belong to neither part.
    """
    rate = 1.0 / float(np.median(np.diff(t)))
    smooth = pd.Series(fz).rolling(max(1, int(round(smooth_s * rate))), center=True, min_periods=1).mean()
    smooth = smooth.to_numpy()
    low, high = float(smooth.min()), float(smooth.max())
    loaded = smooth > 0.5 * (low + high)
    guard = int(round(guard_s * rate))
    return _interior(loaded, guard), _interior(~loaded, guard), high - low


def _mean_std(x: np.ndarray) -> tuple[float, float]:
    return (float(x.mean()), float(x.std(ddof=1))) if len(x) > 1 else (float("nan"), float("nan"))


def reading(t: np.ndarray, fz: np.ndarray, run: str, reference_n: float, min_step_n: float = 1.0,
            source: str | Path = "<recording>") -> dict:
    """Mean and spread of global Fz over the unloaded part and (loaded run) the loaded part of one
    recording, and the deviation from what is really on the sensor. ``source`` names errors."""
    loaded, unloaded, step = split_load(t, fz)
    row = {"n_samples": len(fz), "step_n": step}
    if run == "loaded":
        if step < min_step_n:
            raise InputError(source, f"loaded run, but global Fz never changes by {min_step_n} N "
                                     f"(range {step:.3f} N): no weight was placed")
        if not loaded.any():
            raise InputError(source, "loaded run, but no steady loaded part was found")
    else:
        if step >= min_step_n:
            raise InputError(source, f"unloaded run, but global Fz changes by {step:.2f} N: "
                                     "something was on the sensor")
        loaded, unloaded = np.zeros_like(loaded), np.ones_like(unloaded)
    row["n_unloaded"], row["n_loaded"] = int(unloaded.sum()), int(loaded.sum())
    row["fz_unloaded_mean_n"], row["fz_unloaded_std_n"] = _mean_std(fz[unloaded])
    row["fz_loaded_mean_n"], row["fz_loaded_std_n"] = _mean_std(fz[loaded])
    if run == "loaded":
        row["deviation_n"] = row["fz_loaded_mean_n"] - reference_n
        row["deviation_std_n"] = row["fz_loaded_std_n"]
    else:
        row["deviation_n"], row["deviation_std_n"] = row["fz_unloaded_mean_n"], row["fz_unloaded_std_n"]
    row["reference_n"] = reference_n if run == "loaded" else 0.0
    return row


def recording_reading(path: str | Path, run: str, reference_n: float, sensor: int = 0,
                      min_step_n: float = 1.0) -> dict:
    """`reading` of one shard's global Fz (sensor ``sensor``), refused when a pillar's reading
    was clipped at the sensor's measuring limit (the drift of a clipped reading reads as none)."""
    t, fz = _read_fz(Path(path), sensor)
    _check_clipped(Path(path), sensor)
    return reading(t, fz, run, reference_n, min_step_n, source=path)


# A pillar reading clipped at the sensor's measuring range holds one value exactly, sample after
# sample; with the pillars' noise (about 0.015 N) a reading repeats its extreme by chance on a few
# samples at most. The limit itself is the sensor's, not read from anywhere: it is where the run sits.
CLIPPED_RUN = 10


def _check_clipped(path: Path, sensor: int) -> None:
    columns = [f"fz{i}" for i in range(9)]
    try:
        frame = pd.read_parquet(path, columns=["stamp_ns", "sensor", *columns])
    except (KeyError, ValueError, OSError):
        return                              # a shard without pillar columns: nothing to check
    frame = frame[frame["sensor"] == sensor].sort_values("stamp_ns")
    for col in columns:
        v = frame[col].to_numpy(np.float64)
        if not len(v) or not np.isfinite(v).any():
            continue
        extreme = v[np.nanargmax(np.abs(v))]
        if extreme == 0.0:
            continue
        at = np.concatenate([[False], v == extreme, [False]]).astype(np.int8)
        edges = np.flatnonzero(np.diff(at))
        longest = int((edges[1::2] - edges[::2]).max()) if len(edges) else 0
        if longest >= CLIPPED_RUN:
            raise InputError(path, f"pillar {col[2:]} of sensor {sensor} reads exactly {extreme:.3f} N in Z for "
                                   f"{longest} samples in a row: clipped at the sensor's measuring range, so the "
                                   f"load exceeds what it measures and its drift cannot be read (lighten the "
                                   f"reference load)")


MIN_RECORDINGS_PER_RUN = 3


def drift_series(shard_paths, load_g: float, sensor: int = 0, min_step_n: float = 1.0) -> pd.DataFrame:
    """One row per recording: run, t_min, unloaded baseline, loaded reading, deviation, drift.

    Run and minutes come from the file name ``<run>_t<MM>.parquet`` (InputError naming the file
    otherwise); every name is checked before any file is read. ``drift_n`` is ``deviation_n``
    minus that of the run's first recording; ``baseline_drift_n`` the same for the unloaded part.
    """
    paths = [Path(p) for p in shard_paths]
    named = [(p, *parse_recording_name(p)) for p in paths]
    seen: dict[tuple[str, int], Path] = {}
    for path, run, t_min in named:
        if (run, t_min) in seen:
            raise InputError(path, f"second recording of run {run} at t = {t_min} min "
                                   f"(also {seen[(run, t_min)]})")
        seen[(run, t_min)] = path
    for run in sorted({run for _, run, _ in named}):
        times = sorted(t for _, r, t in named if r == run)
        if len(times) < MIN_RECORDINGS_PER_RUN:
            first = next(path for path, r, _ in named if r == run)
            raise InputError(first.parent, f"run {run} has {len(times)} recording(s) (t = "
                                           f"{', '.join(map(str, times))} min): a drift curve needs at least "
                                           f"{MIN_RECORDINGS_PER_RUN} per run, taken minutes apart (a line fits two; "
                                           f"the third shows whether it holds)")
    reference_n = load_g / 1000.0 * G
    rows = [{"file": path.name, "run": run, "t_min": t_min,
             **recording_reading(path, run, reference_n, sensor, min_step_n)} for path, run, t_min in named]
    columns = ["file", "run", "t_min", "n_samples", "step_n", "n_unloaded", "fz_unloaded_mean_n",
               "fz_unloaded_std_n", "n_loaded", "fz_loaded_mean_n", "fz_loaded_std_n", "reference_n",
               "deviation_n", "deviation_std_n"]
    series = pd.DataFrame(rows, columns=columns)
    series["run_order"] = series["run"].map(RUNS.index)
    series = series.sort_values(["run_order", "t_min"]).drop(columns="run_order").reset_index(drop=True)
    first = series.groupby("run", sort=False)[["deviation_n", "fz_unloaded_mean_n"]].transform(
        lambda column: column.iloc[0])
    series["drift_n"] = series["deviation_n"] - first["deviation_n"]
    series["baseline_drift_n"] = series["fz_unloaded_mean_n"] - first["fz_unloaded_mean_n"]
    return series
