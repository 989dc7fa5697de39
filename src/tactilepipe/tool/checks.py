"""The tool study's cross-key parameter checks: the model's input size against the stored frames,
the variants the runs can name and the network can build, the split's fractions, the kernels
against the threads and device they run on.

Here, not in core/config.py, so that editing them re-runs the tool stages only (the code a stage
runs is an input of its rule: pipeline/codedeps.py). A tool stage run by hand runs them (its
``@command`` ``checks=``); the workflow runs every study's (tactilepipe/studies.py)."""

from __future__ import annotations

import re

from tactilepipe.core.errors import ConfigError


def check(p: dict, source: str) -> None:
    """Raise ConfigError naming ``source`` and the keys when resolved parameters ``p`` disagree."""
    stored = p["tool_ingest"]["stored_size"]
    for where, size in [("tool_train.image_size", p["tool_train"]["image_size"])] + \
            [(f"tool_train.sweep[{i}].image_size", s["image_size"]) for i, s in enumerate(p["tool_train"]["sweep"])]:
        if size > stored:
            raise ConfigError(f"{source}: {where}={size} is larger than tool_ingest.stored_size={stored}: the model "
                              f"would train on upsampled frames (store them larger, or train smaller)")
    _check_variants(p["tool_variants"], p["tool_train"]["variants"], source)
    if abs(sum(p["tool_split"]["fractions"]) - 1.0) > 1e-6:
        raise ConfigError(f"{source}: tool_split.fractions must sum to 1 (got {p['tool_split']['fractions']})")
    for group in ("tool_train", "predict"):
        g = p[group]
        why = kernels_conflict(group, g["kernels"], g["num_threads"], g.get("device"))
        if why:
            raise ConfigError(f"{source}: {why}")


def kernels_conflict(group: str, kernels: str, num_threads: int | None, device: str | None = None) -> str | None:
    """Why kernels ``kernels`` cannot run on ``num_threads`` threads on ``device`` (None: they can).
    Portable kernels give the same bytes on every x86 CPU by running on one CPU thread. The one
    statement of the rule: params.yaml is checked with it before any job, training and the
    estimator with it again on the settings they are given."""
    if kernels == "portable" and num_threads not in (None, 1):
        return (f"{group}.num_threads {num_threads} with kernels: portable, which runs on one thread (the bytes of "
                f"a model depend on the thread count): set num_threads: 1, or kernels: native")
    if kernels == "portable" and device not in (None, "auto", "cpu"):
        return (f"{group}.kernels: portable pins CPU kernels, but the run is on {device}: set kernels: native for "
                f"a GPU run")
    return None


def _check_variants(variants: dict, chosen, source: str) -> None:
    """``tool_variants`` defines 'full', names no other run, slices real channels; ``chosen``
    (tool_train.variants, a list or "all") names defined variants only."""
    if "full" not in variants:
        raise ConfigError(f"{source}: tool_variants must define 'full', the published model (the leave-one-tool-out, "
                          f"sweep and study-000 runs train it)")
    for name, v in variants.items():
        if name.startswith("full_") or re.search(r"_r[0-9]+$", name):
            raise ConfigError(f"{source}: tool_variants.{name}: the name reads as another run (<variant>_r<k> is a "
                              f"variant's repeat k, full_<...> one of the full model's other runs): choose another")
        for a, b in v["sensors"]:
            if a >= b:
                raise ConfigError(f"{source}: tool_variants.{name}.sensors: [{a}, {b}] is no channel slice (start must "
                                  f"be below stop, within the 4 input channels)")
    unknown = [v for v in chosen if v not in variants] if chosen != "all" else []
    if unknown:
        raise ConfigError(f"{source}: tool_train.variants: unknown variant(s) {unknown} (tool_variants defines "
                          f"{', '.join(variants)}; or 'all')")
