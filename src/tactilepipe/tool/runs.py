"""The training runs of a tool scene: their names and what each name trains.

One place for the naming that the workflow, the compute estimate and the report share (which
force a scene learns is in scenes.py). From the parameter groups ``tool_train`` and ``tool_split``:
- ``<variant>``: the variant on repeat 0 of the default split (the run the figures draw);
- ``<variant>_r<k>``: the variant on repeat k (its own split seed and model seed);
- ``full_loto_<tool>``: the full model with that tool left out (every tool in turn);
- ``full_d<depth>_s<size>``: the full model at another depth / input size (the sweep: error
  against run time);
- ``full_<split>``: the full model on another split (study 000's protocols).
"""

from __future__ import annotations

import re

from tactilepipe.core.errors import TactilepipeError
from tactilepipe.tool.data.splits import parse_split_name, split_name
from tactilepipe.tool.model.variants import Architecture


def _listed_variants(tool_train: dict) -> list[str]:
    """``tool_train.variants`` as resolved parameters hold it (core.config.resolve spells "all" out)."""
    variants = tool_train["variants"]
    if not isinstance(variants, list):
        raise TactilepipeError(f"tool_train.variants {variants!r}: expected the resolved list of variant names "
                               f"(core.config.resolve turns 'all' into it)")
    return variants


def sweep_run_name(entry: dict) -> str:
    return f"full_d{entry['depth']}_s{entry['image_size']}"


def repeat_runs(variant: str, repeats: int) -> list[str]:
    """Run names of one variant over the repeats of the default split, repeat 0 first."""
    return [variant if k == 0 else f"{variant}_r{k}" for k in range(repeats)]


def loto_run_name(tool: str) -> str:
    return f"full_loto_{tool}"


def tool_runs(tool_train: dict, repeats: int, tools: list[str]) -> list[str]:
    """Every run of a scene: each variant on every repeat, leave-one-tool-out for every tool
    (when ``tool_train.loto``), then the sweep."""
    runs = [r for v in _listed_variants(tool_train) for r in repeat_runs(v, repeats)]
    runs += [loto_run_name(t) for t in sorted(tools)] if tool_train["loto"] else []
    return runs + [sweep_run_name(s) for s in tool_train["sweep"]]


def run_spec(tool_train: dict, run: str) -> tuple[str, str, int, int]:
    """(variant, split name, depth, image size) of a run name."""
    depth, size, split = tool_train["depth"], tool_train["image_size"], tool_train["split"]
    variants = _listed_variants(tool_train)
    for s in tool_train["sweep"]:
        if run == sweep_run_name(s):
            return "full", split, s["depth"], s["image_size"]
    if run in variants:
        return run, split, depth, size
    m = re.fullmatch(r"(.+)_r([1-9][0-9]*)", run)
    if m and m.group(1) in variants:
        return m.group(1), split_name(split, int(m.group(2))), depth, size
    if run.startswith("full_"):
        other = run[len("full_"):]
        parse_split_name(other)          # refuses a name that is no split
        return "full", other, depth, size
    raise TactilepipeError(f"run '{run}': not a tool run (variants {variants}, <variant>_r<k>, "
                           f"full_loto_<tool>, full_d<depth>_s<size> of tool_train.sweep, full_<split>)")


def run_definition(params: dict, run: str) -> dict:
    """What a training run reads besides the tool_train settings, from the resolved parameters: its
    name, its variant's name and architecture (what the network builds; the variant's label,
    colour and baseline are the report's), its split, depth and input size."""
    variant, split, depth, size = run_spec(params["tool_train"], run)
    arch = Architecture.from_dict(params["tool_variants"][variant]).as_dict()
    return {"name": run, "variant": {"name": variant, **arch}, "split": split, "depth": depth, "image_size": size}


def run_source_keys(tool_train: dict, run: str) -> tuple[str, ...]:
    """The params.yaml keys a run's definition is taken from: its variant's entry; the split from
    tool_train.split for a variant's repeats and the sweep (the others name theirs); the depth and
    size from the run's entry of tool_train.sweep, or else tool_train.depth and image_size."""
    variant = run_spec(tool_train, run)[0]
    if run in {sweep_run_name(s) for s in tool_train["sweep"]}:
        return f"tool_variants.{variant}", "tool_train.split", "tool_train.sweep"
    repeat = run in _listed_variants(tool_train) or re.fullmatch(r"(.+)_r[1-9][0-9]*", run) is not None
    return (f"tool_variants.{variant}",) + (("tool_train.split",) if repeat else ()) + \
        ("tool_train.depth", "tool_train.image_size")
