"""The simulator as the labels' oracle: every kept frame pair's label against the true wrench.

A simulated trial knows the force on the Nano17 at every instant. A frame pair's label should be
that force at the moment its two frames were exposed (the mean of the two exposures). After ingest
and the dataset stage, ``label_errors`` reads samples.parquet and gives each kept trial's label
error against that truth, normal and shear, and ``within_budget`` judges it against the budget
written in docs/robustness.md ("The label error budget").
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.tool.sim.trial import Trial

# The budget of a kept trial's labels (docs/robustness.md): the mean error and the 95th percentile
# of the error, each a floor (the 10-bit ADC's 0.066 N count, the 15-Hz log between two samples,
# the clock's few ms) plus a share of the trial's peak force (a steeper press gives a clock error
# more force to show). Clean trials of the default session use up to about half of it.
BUDGET_MAE_N = (0.15, 0.02)          # N + share of the trial's peak |label|
BUDGET_P95_N = (0.4, 0.06)


def budget(peak_n: float) -> dict:
    return {"mae": BUDGET_MAE_N[0] + BUDGET_MAE_N[1] * peak_n, "p95": BUDGET_P95_N[0] + BUDGET_P95_N[1] * peak_n}


def truth_at_pairs(trial: Trial, t_ns: np.ndarray) -> np.ndarray:
    """True (fx, fy, fz) at each pair's mean exposure (t_ns: the mean of the two frames' stamps)."""
    tau = (np.asarray(t_ns, np.float64) - trial.t0_ns) / 1e9 - float(np.mean(trial.rig["latency_s"]))
    return trial.sensor_wrench(tau)[:, :3]


def label_errors(data_dir: Path, trials: dict[str, Trial], normal_sign: float = -1.0) -> dict[str, dict]:
    """Per kept trial (its name without the session; ``trials``: name -> the simulated Trial it was
    written from): label MAE, 95th percentile and max of the error, and the trial's true peak, for
    the label of the data set's kind."""
    samples = pd.read_parquet(data_dir / "samples.parquet")
    out = {}
    for trial_name, rows in samples.groupby("trial", sort=False):
        name = trial_name.split("/")[-1]
        trial = trials[name]
        truth = truth_at_pairs(trial, rows["t_ns"].to_numpy())
        if trial.spec.kind == "normal":
            label, true = rows["normal"].to_numpy(), normal_sign * truth[:, 2]
        else:
            label, true = rows["shear"].to_numpy(), np.hypot(truth[:, 0], truth[:, 1])
        err = np.abs(label - true)
        out[name] = {"kind": trial.spec.kind, "mae": float(err.mean()), "p95": float(np.percentile(err, 95)),
                     "max": float(err.max()), "peak": float(np.abs(true).max()), "pairs": int(len(err))}
    return out


def over_budget(errors: dict) -> dict[str, str]:
    """Trial -> how it breaks the budget, for each kept trial that does."""
    out = {}
    for name, e in errors.items():
        b = budget(e["peak"])
        broken = [f"{k} {e[k]:.3f} N > {b[k]:.3f} N" for k in ("mae", "p95") if e[k] > b[k]]
        if broken:
            out[name] = "; ".join(broken) + f" (peak {e['peak']:.2f} N)"
    return out
