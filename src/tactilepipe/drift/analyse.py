"""Drift analysis of study 001 (section 3): per-recording readings, model fits, recalibration time.

What the paper's Figure 5 "deviation from the reference weight" is taken to mean: the reading
error, i.e. what the sensor reports minus what is really on it. Unloaded run: the reference is
0 N, so the deviation is the mean global Fz itself. Loaded run: the mean global Fz while the
weight is on, minus its true weight (load_g * 9.81 N). That is the number that matters when the
sensor weighs something, and the one the paper's "+0.5 N with 500 g" describes. The loaded run's
unloaded parts (before and after the weight) are kept as a baseline column for comparison.

Drift is the deviation relative to the run's first recording (the one taken right after the
driver's bias request), so it is 0 at t = 0 up to that recording's noise; recordings and the
loaded/unloaded parts are found from the forces alone, so real bags are analysed the same way.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import minimize_scalar

from tactilepipe.core.atomic import write_json, write_text
from tactilepipe.drift import RUNS, parse_recording_name
from tactilepipe.core.errors import InputError
from tactilepipe.core.metrics import r2_score

G = 9.81
EXP_MODEL = "exp_saturating"
R2_NOTE = ("r2: in-sample R² of the fit on all recordings of the run; loo_r2: leave-one-out "
           "predictive R² = 1 - PRESS / SS_tot (each recording predicted by the model fitted "
           "on the others; SS_tot about the run's mean)")


# --- per-recording readings -------------------------------------------------------------------

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
    """`reading` of one shard's global Fz (sensor ``sensor``)."""
    t, fz = _read_fz(Path(path), sensor)
    return reading(t, fz, run, reference_n, min_step_n, source=path)


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


# --- models -----------------------------------------------------------------------------------

@dataclass(frozen=True)
class FittedModel:
    """A fitted drift curve y(t), t in minutes: a polynomial or c + A (1 - exp(-t / tau))."""
    name: str
    kind: str                  # "poly" or "exp"
    coef: tuple[float, ...]    # poly: c0, c1, ... (increasing powers); exp: c, A, tau_min

    @property
    def n_params(self) -> int:
        return len(self.coef)

    def predict(self, t) -> np.ndarray:
        t = np.asarray(t, float)
        if self.kind == "poly":
            return np.polynomial.polynomial.polyval(t, self.coef)
        c, amplitude, tau = self.coef
        return c + amplitude * (1.0 - np.exp(-t / tau))

    def params(self) -> dict[str, float]:
        if self.kind == "poly":
            return {f"c{i}": float(c) for i, c in enumerate(self.coef)}
        return dict(zip(("c_n", "amplitude_n", "tau_min"), map(float, self.coef)))


def fit_poly(t, y, degree: int) -> FittedModel:
    coef = np.polynomial.polynomial.polyfit(np.asarray(t, float), np.asarray(y, float), degree)
    return FittedModel(f"poly{degree}", "poly", tuple(float(c) for c in coef))


def _exp_linear_part(t, y, tau):
    basis = np.column_stack([np.ones_like(t), 1.0 - np.exp(-t / tau)])
    (c, amplitude), *_ = np.linalg.lstsq(basis, y, rcond=None)
    return c, amplitude, float(((basis @ (c, amplitude) - y) ** 2).sum())


def fit_saturating(t, y, tau_bounds_min=(0.5, 1e4)) -> FittedModel:
    """Least squares c + A (1 - exp(-t / tau)): linear in (c, A) for a given tau, so tau is found
    by a coarse log grid then a bounded refinement (no starting guess that could fail to converge).
    At the upper tau bound the curve is practically a straight line over the observation."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    grid = np.geomspace(*tau_bounds_min, 200)
    sse = [_exp_linear_part(t, y, tau)[2] for tau in grid]
    i = int(np.argmin(sse))
    lo, hi = np.log(grid[max(i - 1, 0)]), np.log(grid[min(i + 1, len(grid) - 1)])
    best = minimize_scalar(lambda lt: _exp_linear_part(t, y, np.exp(lt))[2], bounds=(lo, hi),
                           method="bounded", options={"xatol": 1e-6})
    tau = float(np.exp(best.x)) if best.fun <= sse[i] else float(grid[i])
    c, amplitude, _ = _exp_linear_part(t, y, tau)
    return FittedModel(EXP_MODEL, "exp", (float(c), float(amplitude), tau))


def _fitters(degrees) -> dict:
    fitters = {f"poly{d}": (d + 1, lambda t, y, d=d: fit_poly(t, y, d)) for d in sorted(set(degrees))}
    fitters[EXP_MODEL] = (3, fit_saturating)
    return fitters


def loo_r2(t, y, fitter) -> float:
    """Leave-one-out predictive R²: 1 - sum (y_i - f_{-i}(t_i))² / sum (y_i - mean y)²."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    keep = ~np.eye(len(t), dtype=bool)
    predicted = np.array([fitter(t[k], y[k]).predict(t[i]) for i, k in enumerate(keep)])
    return r2_score(y, predicted)


def recalibration_interval(model: FittedModel, t_max: float, tolerance_n: float) -> float | None:
    """First time (min) in [0, t_max] at which |f(t) - f(0)| exceeds the tolerance, else None.

    f(0) is the fitted reading right after the bias request: recalibrating resets the drift since
    then, not any offset left by the bias itself. Beyond the observation we do not extrapolate.
    """
    grid = np.linspace(0.0, t_max, 3001)
    excess = np.abs(model.predict(grid) - model.predict(0.0)) - tolerance_n
    over = np.flatnonzero(excess > 0)
    if len(over) == 0:
        return None
    if over[0] == 0:
        return 0.0
    lo, hi = grid[over[0] - 1], grid[over[0]]
    for _ in range(60):  # bisection on the bracketing grid step
        mid = 0.5 * (lo + hi)
        if abs(model.predict(mid) - model.predict(0.0)) > tolerance_n:
            hi = mid
        else:
            lo = mid
    return float(hi)


@dataclass
class DriftFits:
    table: pd.DataFrame                                   # one row per (run, model)
    models: dict[str, dict[str, FittedModel]]             # run -> model name -> fit
    best_model: dict[str, str | None]                     # run -> model with the best LOO R²
    recalibration_interval_min: dict[str, float | None]   # run -> minutes, None if beyond observed
    recalibration_beyond_observed: dict[str, bool]
    observed_until_min: dict[str, float]
    cross_run_r2: dict[str, dict[str, float]] = field(default_factory=dict)  # "a->b" -> model -> R²


def fit_models(series: pd.DataFrame, degrees, tolerance_n: float, column: str = "drift_n") -> DriftFits:
    """Per run: polynomial fits of each degree and the saturating exponential, with in-sample and
    leave-one-out R²; best model by LOO R² (fewer parameters on ties); the recalibration interval
    it implies; and cross-run R² (fit on one run, scored on another, as the paper did).

    A model needs at least as many recordings as parameters (two more for a LOO score); with
    fewer it is left out (in-sample) or its loo_r2 is NaN.
    """
    fitters = _fitters(degrees)
    rows, models, best, interval, beyond, until = [], {}, {}, {}, {}, {}
    runs = [r for r in RUNS if r in set(series["run"])]
    for run in runs:
        part = series[series["run"] == run].sort_values("t_min")
        t, y = part["t_min"].to_numpy(float), part[column].to_numpy(float)
        models[run], until[run] = {}, float(t.max())
        for name, (n_params, fitter) in fitters.items():
            if len(t) < n_params:
                continue
            model = fitter(t, y)
            models[run][name] = model
            rows.append({"run": run, "model": name, "n_params": n_params, "n_points": len(t),
                         "r2": r2_score(y, model.predict(t)),
                         "loo_r2": loo_r2(t, y, fitter) if len(t) >= n_params + 2 else float("nan"),
                         "fitted_drift_end_n": float(model.predict(t.max()) - model.predict(0.0)),
                         "params": json.dumps({k: round(v, 6) for k, v in model.params().items()})})
    table = pd.DataFrame(rows, columns=["run", "model", "n_params", "n_points", "r2", "loo_r2",
                                        "fitted_drift_end_n", "params"])
    table["best"] = False
    for run in runs:
        part = table[table["run"] == run]
        score = part["loo_r2"] if part["loo_r2"].notna().any() else part["r2"]
        ranked = part.assign(score=score).dropna(subset=["score"]).sort_values(
            ["score", "n_params"], ascending=[False, True])
        best[run] = None if ranked.empty else str(ranked["model"].iloc[0])
        if best[run] is None:
            interval[run], beyond[run] = None, False
            continue
        table.loc[ranked.index[0], "best"] = True
        interval[run] = recalibration_interval(models[run][best[run]], until[run], tolerance_n)
        beyond[run] = interval[run] is None
    fits = DriftFits(table, models, best, interval, beyond, until)
    for a in runs:
        for b in runs:
            if a == b:
                continue
            target = series[series["run"] == b]
            t, y = target["t_min"].to_numpy(float), target[column].to_numpy(float)
            fits.cross_run_r2[f"{a}->{b}"] = {name: r2_score(y, m.predict(t)) for name, m in models[a].items()
                                              if name in models[b]}
    return fits


# --- outputs ----------------------------------------------------------------------------------

def _finite_or_none(x):
    if isinstance(x, dict):
        return {k: _finite_or_none(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite_or_none(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def metrics_dict(series: pd.DataFrame, fits: DriftFits, tolerance_n: float) -> dict:
    last = series.groupby("run", sort=False).tail(1).set_index("run")
    fit_summary = {run: {row.model: {"r2": row.r2, "loo_r2": row.loo_r2, "n_params": row.n_params,
                                     "params": json.loads(row.params)}
                         for row in fits.table[fits.table["run"] == run].itertuples()}
                   for run in fits.models}
    return _finite_or_none({
        "drift_30min_n": last["drift_n"].to_dict(),                # observed, last minus first recording
        "baseline_drift_30min_n": last["baseline_drift_n"].to_dict(),  # unloaded parts only
        "observed_until_min": fits.observed_until_min,
        "reference_n": last["reference_n"].to_dict(),
        "fits": fit_summary,
        "r2_note": R2_NOTE,
        "best_model": fits.best_model,
        "recalibration_interval_min": fits.recalibration_interval_min,
        "recalibration_beyond_observed": fits.recalibration_beyond_observed,
        "tolerance_n": tolerance_n,
        "cross_run_r2": fits.cross_run_r2,
    })


def _fmt(x, digits=3) -> str:
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.{digits}f}"


def fits_markdown(fits: DriftFits, tolerance_n: float) -> str:
    lines = ["# Drift model fits", "", R2_NOTE + ".", "",
             "| run | model | params | R² (in-sample) | LOO R² | fitted drift at end (N) | best |",
             "|---|---|---:|---:|---:|---:|:-:|"]
    for row in fits.table.itertuples():
        lines.append(f"| {row.run} | {row.model} | {row.n_params} | {_fmt(row.r2)} | {_fmt(row.loo_r2)} | "
                     f"{_fmt(row.fitted_drift_end_n)} | {'✓' if row.best else ''} |")
    lines += ["", f"## Recalibration interval (tolerance {tolerance_n} N, best model)", "",
              "| run | best model | interval (min) |", "|---|---|---:|"]
    for run, minutes in fits.recalibration_interval_min.items():
        text = _fmt(minutes, 1) if minutes is not None else \
            f"beyond the observed {fits.observed_until_min[run]:g} min"
        lines.append(f"| {run} | {fits.best_model[run]} | {text} |")
    if fits.cross_run_r2:
        names = sorted({m for scores in fits.cross_run_r2.values() for m in scores})
        lines += ["", "## Cross-run R² (fitted on one run, scored on the other)", "",
                  "| fitted on -> scored on | " + " | ".join(names) + " |",
                  "|---|" + "---:|" * len(names)]
        for pair, scores in fits.cross_run_r2.items():
            lines.append(f"| {pair.replace('->', ' → ')} | " + " | ".join(_fmt(scores.get(m)) for m in names) + " |")
    return "\n".join(lines) + "\n"


def run(shards, session_meta: str | Path, out_dir: str | Path, params: dict) -> dict:
    """Shards of one drift session and its session.json -> metrics.json, drift_series.csv,
    fits.csv, fits.md, figure."""
    from tactilepipe.drift import read_session_meta
    from tactilepipe.drift.figures import write_drift_figure  # matplotlib only when writing outputs

    out_dir = Path(out_dir)
    tolerance = params["drift"]["tolerance_n"]
    series = drift_series(shards, load_g=read_session_meta(session_meta)["reference_load_g"])
    fits = fit_models(series, params["drift"]["poly_degrees"], tolerance)
    metrics = metrics_dict(series, fits, tolerance)
    write_text(out_dir / "drift_series.csv", series.to_csv(index=False, float_format="%.6g"))
    write_text(out_dir / "fits.csv", fits.table.to_csv(index=False, float_format="%.6g"))
    write_text(out_dir / "fits.md", fits_markdown(fits, tolerance))
    write_drift_figure(out_dir / "figures" / "drift_curves.png", series, fits, tolerance)
    write_json(out_dir / "metrics.json", metrics)
    return metrics
