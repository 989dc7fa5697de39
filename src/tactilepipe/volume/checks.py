"""The volume study's cross-key parameter checks: what the schema cannot say, because it relates
keys (the folds and the simulated lifts, the baseline's mu range, the grid's modality, the
simulator's friction and container).

Here, not in core/config.py, so that editing them re-runs the volume stages only (the code a stage
runs is an input of its rule: pipeline/codedeps.py). A volume stage run by hand runs them (its
``@command`` ``checks=``); the workflow runs every study's (tactilepipe/studies.py)."""

from __future__ import annotations

from tactilepipe.core.errors import ConfigError
from tactilepipe.core.simulated import is_simulated


def check(p: dict, source: str) -> None:
    """Raise ConfigError naming ``source`` and the keys when resolved parameters ``p`` disagree."""
    folds, sim = p["folds"], p["simulate_volume"]
    need = folds["train_lifts_per_volume"] + folds["test_lifts_per_volume"]
    if any(is_simulated(s) for s in p["volume_sessions"]) and sim["lifts_per_volume"] < need:
        raise ConfigError(
            f"{source}: simulate_volume.lifts_per_volume={sim['lifts_per_volume']} is fewer than the "
            f"{need} lifts per volume the folds need (train {folds['train_lifts_per_volume']} + "
            f"test {folds['test_lifts_per_volume']})")
    if p["baseline"]["mu_min"] >= p["baseline"]["mu_max"]:
        raise ConfigError(f"{source}: baseline.mu_min must be below baseline.mu_max")
    if p["mlp"]["grid"]["modality"] not in p["mlp"]["modalities"]:
        raise ConfigError(f"{source}: mlp.grid.modality '{p['mlp']['grid']['modality']}' is not one of "
                          f"mlp.modalities {sorted(p['mlp']['modalities'])}")
    if sim["friction_kinetic"] > sim["friction_static"]:
        raise ConfigError(f"{source}: simulate_volume.friction_kinetic must not exceed friction_static")
    pos = sim["position"]
    fullest = max(sim["volumes_ml"] + sim["unseen_volumes_ml"])
    if pos["container_capped"] and pos["container_capacity_ml"] <= fullest:
        raise ConfigError(f"{source}: simulate_volume.position.container_capacity_ml={pos['container_capacity_ml']:g} "
                          f"leaves no headspace above the fullest volume ({fullest:g} ml)")
