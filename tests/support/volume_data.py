"""Volume-scene samples that follow the algebraic baseline formula exactly, with their folds."""

from __future__ import annotations

import numpy as np
import pandas as pd

from tactilepipe.volume.folds import make_folds


def baseline_data(mu_true: float, p: dict, seed: int = 0) -> tuple[pd.DataFrame, list[dict]]:
    """Samples that follow the baseline formula exactly for mu_true (Fz varies independently)."""
    rng = np.random.default_rng(seed)
    rows = []
    for v in np.arange(0.0, 301.0, 50.0):
        for i in range(4):
            fz = 6.0 * (1 + 0.1 * rng.standard_normal(30))
            fy = (v + p["container_mass_g"]) * p["gravity"] / 1000.0 - mu_true * fz
            rows.append(pd.DataFrame({"lift": f"v{v:g}_{i}", "volume_ml": v, "set": "main", "fy0": fy, "fz0": fz}))
    data = pd.concat(rows, ignore_index=True)
    return data, make_folds(data.drop_duplicates("lift"), 3, 3, 1, seed=seed)
