"""Drift analysis of study 001 (section 3): model fits of the per-recording readings
(drift/recordings.py), recalibration time.

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
from tactilepipe.core.metric_rows import write_metric_rows
from tactilepipe.core.metrics import r2_score
from tactilepipe.core.tables import markdown_html
from tactilepipe.drift import RUNS
from tactilepipe.drift.recordings import drift_series
EXP_MODEL = "exp_saturating"
R2_NOTE = ("r2: in-sample R² of the fit on all recordings of the run; loo_r2: leave-one-out "
           "predictive R² = 1 - PRESS / SS_tot (each recording predicted by the model fitted "
           "on the others; SS_tot about the run's mean)")


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


# DVC's metrics, a row per run (core/metric_rows.py): what drifted in 30 min and how often to
# recalibrate; the fits are in scores.json. A run the session lacks has a row of nulls.
HEADLINE = ("drift_30min_n", "recalibration_interval_min")


def headline(metrics: dict) -> dict[str, dict]:
    return {run: {k: (metrics[k] or {}).get(run) for k in HEADLINE} for run in RUNS}


def run(shards, session_meta: str | Path, out_dir: str | Path, params: dict) -> dict:
    """Shards of one drift session and its session.json -> scores.json (every number; returned),
    metrics/<run>.json (its headline: HEADLINE), drift_series.csv, fits.csv, fits.md (and its HTML
    twin), figure."""
    from tactilepipe.drift import read_session_meta
    from tactilepipe.drift.figures import write_drift_figure  # matplotlib only when writing outputs

    out_dir = Path(out_dir)
    tolerance = params["drift"]["tolerance_n"]
    series = drift_series(shards, load_g=read_session_meta(session_meta)["reference_load_g"])
    fits = fit_models(series, params["drift"]["poly_degrees"], tolerance)
    metrics = metrics_dict(series, fits, tolerance)
    write_text(out_dir / "drift_series.csv", series.to_csv(index=False, float_format="%.6g"))
    write_text(out_dir / "fits.csv", fits.table.to_csv(index=False, float_format="%.6g"))
    page = fits_markdown(fits, tolerance)
    write_text(out_dir / "fits.md", page)
    write_text(out_dir / "fits.html", markdown_html(page))     # what the Snakemake report shows
    write_drift_figure(out_dir / "figures" / "drift_curves.png", series, fits, tolerance)
    write_json(out_dir / "scores.json", metrics)
    write_metric_rows(out_dir, headline(metrics))
    return metrics
