"""Where the noise of a paired MAE difference comes from: split composition, model seed, test sampling.

Two variants trained on S splits with M model seeds each give paired differences d[s, m] (variant
A's test MAE minus B's, same split, same seed index). A one-way nested model splits their variance:
- model seed: the spread over seeds on one split, sigma2_seed = mean over s of var_m(d[s, :]);
- split: the spread of the split means beyond what seed noise explains,
  sigma2_split = var_s(mean_m d[s, :]) - sigma2_seed / M (0 when negative);
- test sampling: the part of the split term that comes from drawing a finite test set, measured
  inside each run by resampling its test trials (a cluster bootstrap: frames of one trial move
  together), sigma2_test = mean over runs of the bootstrap variance of the MAE difference. What is
  left of the split term, sigma2_split - sigma2_test, is the training set's composition.

With K splits and M seeds per split, the variance of the mean difference is modelled as
(1/K + n_test/n_train) * sigma2_split + sigma2_seed / (K * M): splits share training trials, so their
term keeps the Nadeau-Bengio floor; seeds are drawn independently, so theirs falls as 1/(K M).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from tactilepipe.core.errors import TactilepipeError


def bootstrap_difference_variance(abs_err_a, abs_err_b, trials, n_boot: int = 400, seed: int = 0) -> float:
    """Variance of mean(|e_a|) - mean(|e_b|) over test sets redrawn by whole trials (cluster bootstrap);
    NaN for a test set of one trial, whose sampling cannot be measured from inside."""
    diff = np.asarray(abs_err_a, np.float64) - np.asarray(abs_err_b, np.float64)
    codes, inverse = np.unique(np.asarray(trials), return_inverse=True)
    if len(codes) < 2:
        return math.nan
    sums = np.bincount(inverse, weights=diff, minlength=len(codes))
    counts = np.bincount(inverse, minlength=len(codes)).astype(np.float64)
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, len(codes), size=(n_boot, len(codes)))
    means = sums[picks].sum(axis=1) / counts[picks].sum(axis=1)
    return float(means.var(ddof=1))


def decompose(d, test_var, test_train_ratio: float) -> dict:
    """The variance components of paired differences ``d`` (S splits x M seeds) and the bootstrap
    test-sampling variances ``test_var`` of the same runs."""
    d = np.asarray(d, np.float64)
    test_var = np.asarray(test_var, np.float64)
    if d.ndim != 2 or d.shape[0] < 2 or d.shape[1] < 2 or test_var.shape != d.shape:
        raise TactilepipeError(f"decompose: need at least 2 splits x 2 seeds of differences and a test variance "
                               f"for each, got {d.shape} and {test_var.shape}")
    n_splits, n_seeds = d.shape
    seed = float(d.var(axis=1, ddof=1).mean())
    split = max(0.0, float(d.mean(axis=1).var(ddof=1)) - seed / n_seeds)
    test = float(np.nanmean(test_var)) if np.isfinite(test_var).any() else math.nan
    return {"mean": float(d.mean()), "splits": n_splits, "seeds": n_seeds, "var_seed": seed, "var_split": split,
            "var_test": test, "var_composition": max(0.0, split - test) if math.isfinite(test) else math.nan,
            "test_train_ratio": test_train_ratio}


def half_width(parts: dict, repeats: int, seeds: int, level: float = 0.95) -> float:
    """The interval half-width of the mean difference under K = ``repeats`` splits and ``seeds`` seeds
    per split (the model in the module's docstring; t with K*seeds - 1 degrees of freedom)."""
    var = (1.0 / repeats + parts["test_train_ratio"]) * parts["var_split"] + parts["var_seed"] / (repeats * seeds)
    dof = max(repeats * seeds - 1, 1)
    return float(stats.t.ppf(0.5 + level / 2, dof)) * math.sqrt(var)
