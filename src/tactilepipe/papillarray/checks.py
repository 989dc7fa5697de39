"""The PapillArray sensor's cross-key parameter check: ``papillarray_axes`` maps each recorded axis
once. The volume and drift stages (and ``papillarray-ingest``) run it by hand; the workflow runs
every study's checks (tactilepipe/studies.py). Here, with the sensor, so that editing it re-runs
the PapillArray stages only."""

from __future__ import annotations

from tactilepipe.core.errors import ConfigError


def check(p: dict, source: str) -> None:
    """Raise ConfigError naming ``source`` and the sensor whose axis map is no permutation."""
    for sensor, axes in p["papillarray_axes"].items():
        if sorted(v[1] for v in axes.values()) != ["x", "y", "z"]:
            raise ConfigError(f"{source}: papillarray_axes.{sensor} must take each recorded axis x, y, z once "
                              f"(got {axes})")
