"""Train/test lift draws of study 001: per fold, a seeded random ``n_train`` lifts of every volume
for training and ``n_test`` others for testing (the paper's "5-fold" are 5 such draws)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from tactilepipe.core.errors import InputError


def make_folds(lifts: pd.DataFrame, n_folds: int, n_train: int, n_test: int, seed: int,
               source: str = "lifts") -> list[dict]:
    """lifts: one row per lift with columns lift, volume_ml, set; only set == 'main' is split."""
    main = lifts[lifts["set"] == "main"]
    counts = main.groupby("volume_ml")["lift"].nunique()
    short = counts[counts < n_train + n_test]
    if len(short):
        detail = ", ".join(f"{v:g} ml has {c}" for v, c in short.items())
        raise InputError(source, f"too few lifts for the folds ({detail}; each volume needs "
                                 f"{n_train + n_test} = {n_train} train + {n_test} test)")
    if len(counts) < 2:
        raise InputError(source, f"need at least two volumes to fit a regression, found {list(counts.index)}")
    rng = np.random.default_rng(np.random.SeedSequence([seed, 4242]))
    folds = []
    for k in range(n_folds):
        train, test = [], []
        for volume in sorted(counts.index):
            ids = sorted(main.loc[main["volume_ml"] == volume, "lift"].unique())
            pick = rng.permutation(len(ids))
            train += [ids[i] for i in pick[:n_train]]
            test += [ids[i] for i in pick[n_train:n_train + n_test]]
        folds.append({"fold": k, "train": sorted(train), "test": sorted(test)})
    return folds
