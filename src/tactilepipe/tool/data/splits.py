"""Train/validation/test splits of a tool dataset, written as files.

- ``frame``: the public code's random frame-level 70/15/15. Adjacent frames of one press land in
  different splits, so test frames have near-copies in training: kept only for comparison.
- ``public_frame``: ``frame`` with the label statistics of every frame, as the public code takes
  them before splitting: the paper's protocol, leak included, for reproducing it only.
- ``trial`` (default): whole trials go to one split, 70/15/15 by frame count, stratified by tool
  when every tool has at least 3 trials (each tool then has trials in every split, so the per-tool
  errors are measured on every tool and no tool is learnt from one or two grasps).
- ``loto_<tool>``: leave that tool out (the tool is the test set).
- ``lopo``: leave one grasp pose out (one pose of every tool is the test set).
- ``<kind>_r<k>`` (k >= 1): repeat k of a drawn split, from its own seed, so that a score can be
  reported over several draws (``tool_split.repeats``); the unsuffixed name is repeat 0.
Label normalisation statistics are computed from the training split only (but for public_frame).
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd

from tactilepipe.core.errors import InputError


def _group_split(groups: pd.Series, fractions: tuple[float, float, float], rng) -> tuple[np.ndarray, ...]:
    """Assign whole groups to train/val/test so each gets about its fraction of the rows.

    Test and validation get one group each first (so few groups still fill every split), then
    each group goes to the split furthest below its target share.
    """
    sizes = groups.value_counts()
    if len(sizes) < 3:
        raise InputError("splits", f"need at least 3 trials for a train/validation/test split, found {len(sizes)}")
    order = rng.permutation(sizes.index.to_numpy())
    assign = {order[0]: 2, order[1]: 1}
    filled = np.array([0.0, sizes[order[1]], sizes[order[0]]])
    target = np.asarray(fractions) * len(groups)
    for g in order[2:]:
        k = int(np.argmax((target - filled) / target))
        assign[g] = k
        filled[k] += sizes[g]
    part = groups.map(assign).to_numpy()
    return tuple(np.flatnonzero(part == k) for k in range(3))


def _trial_split(samples: pd.DataFrame, fractions, rng) -> tuple[np.ndarray, ...]:
    """Whole trials to train/validation/test; within each tool when every tool has >= 3 trials."""
    per_tool = samples.groupby("tool")["trial"].nunique()
    if per_tool.min() < 3:            # too few trials to give every tool a test and a validation trial
        return _group_split(samples["trial"], fractions, rng)
    parts = [[], [], []]
    for tool in sorted(per_tool.index):
        rows = np.flatnonzero(samples["tool"].to_numpy() == tool)
        for k, idx in enumerate(_group_split(samples["trial"].iloc[rows].reset_index(drop=True), fractions, rng)):
            parts[k].append(rows[idx])
    return tuple(np.sort(np.concatenate(p)) for p in parts)


KINDS = ("frame", "public_frame", "trial", "loto", "lopo")


def parse_split_name(name: str) -> tuple[str, int, str | None]:
    """(kind, repeat, held-out tool) of a split name: ``trial``, ``trial_r2``, ``loto_spatula``, ..."""
    if name.startswith("loto_") and len(name) > len("loto_"):
        return "loto", 0, name[len("loto_"):]
    m = re.fullmatch(r"([a-z_]+?)(?:_r([1-9][0-9]*))?", name)
    if not m or m.group(1) not in KINDS or m.group(1) == "loto":
        raise InputError("splits", f"unknown split '{name}' (one of {', '.join(k for k in KINDS if k != 'loto')}, "
                                   f"each optionally with _r<k> for repeat k; or loto_<tool>)")
    return m.group(1), int(m.group(2) or 0), None


def split_name(kind: str, repeat: int) -> str:
    """The file name (without .json) of repeat ``repeat`` of a split kind."""
    return kind if repeat == 0 else f"{kind}_r{repeat}"


def label_stats(labels: np.ndarray) -> dict:
    return {"min": float(labels.min()), "max": float(labels.max()), "mean": float(labels.mean()),
            "std": float(labels.std()) or 1.0}


def make_split(samples: pd.DataFrame, name: str, label: str, seed: int, fractions=(0.7, 0.15, 0.15),
               holdout_pose: int = 0) -> dict:
    """The split ``name`` (see ``parse_split_name``) of ``samples``; repeat k draws from its own
    seed sequence, and repeat 0 from the one every earlier result used."""
    kind, repeat, holdout_tool = parse_split_name(name)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 31337] + ([repeat] if repeat else [])))
    if kind in ("frame", "public_frame"):
        idx = rng.permutation(len(samples))
        a, b = int(fractions[0] * len(idx)), int((fractions[0] + fractions[1]) * len(idx))
        train, val, test = np.sort(idx[:a]), np.sort(idx[a:b]), np.sort(idx[b:])
    elif kind == "trial":
        train, val, test = _trial_split(samples, fractions, rng)
    elif kind == "loto":
        tools = sorted(samples["tool"].unique())
        if holdout_tool not in tools:
            raise InputError("splits", f"held-out tool '{holdout_tool}' is not in the data ({tools})")
        test = np.flatnonzero(samples["tool"] == holdout_tool)
        rest = samples[samples["tool"] != holdout_tool]
        tr, va = _two_way(rest["trial"], 0.85, rng)
        train, val = rest.index.to_numpy()[tr], rest.index.to_numpy()[va]
    elif kind == "lopo":
        rank = samples.groupby("tool")["pose"].transform(lambda p: p.map({v: i for i, v in enumerate(sorted(p.unique()))}))
        test = np.flatnonzero(rank == holdout_pose)
        if len(test) == 0:
            raise InputError("splits", f"no tool has a pose number {holdout_pose}")
        rest = samples[rank != holdout_pose]
        tr, va = _two_way(rest["trial"], 0.85, rng)
        train, val = rest.index.to_numpy()[tr], rest.index.to_numpy()[va]
    stats_rows = np.arange(len(samples)) if kind == "public_frame" else train
    return {"name": name, "kind": kind, "repeat": repeat, "leaky": kind in ("frame", "public_frame"), "label": label,
            "train": train.tolist(), "validation": val.tolist(), "test": test.tolist(),
            "label_stats": label_stats(samples[label].to_numpy()[stats_rows]),
            "trials": {k: sorted(samples["trial"].iloc[v].unique().tolist())
                       for k, v in (("train", train), ("validation", val), ("test", test))}}


def _two_way(groups: pd.Series, train_fraction: float, rng) -> tuple[np.ndarray, np.ndarray]:
    sizes = groups.value_counts()
    if len(sizes) < 2:
        raise InputError("splits", "need at least two trials outside the held-out set")
    order = rng.permutation(sizes.index.to_numpy())
    filled, assign = 0, {}
    for g in order:
        assign[g] = 0 if filled < train_fraction * len(groups) else 1
        filled += sizes[g]
    if all(v == 0 for v in assign.values()):
        assign[order[-1]] = 1
    part = groups.map(assign).to_numpy()
    return np.flatnonzero(part == 0), np.flatnonzero(part == 1)


def thin_training(split: dict, samples: pd.DataFrame, seed: int, trial_fraction: float = 1.0,
                  frame_stride: int = 1) -> dict:
    """The split with a smaller training set (validation, test and label scaling unchanged), for
    learning curves: ceil(trial_fraction x n) of each tool's training trials (nested as the fraction
    grows, for one seed), and of those every ``frame_stride``-th frame of each trial."""
    if not 0 < trial_fraction <= 1 or frame_stride < 1:
        raise InputError("splits", f"trial_fraction must be in (0, 1] and frame_stride >= 1, got "
                                   f"{trial_fraction} and {frame_stride}")
    train = np.asarray(split["train"])
    rows = samples.iloc[train]
    keep = []
    for _, group in rows.groupby("tool"):
        trials = np.random.default_rng([seed, 7]).permutation(sorted(group["trial"].unique()))
        keep += list(trials[: int(np.ceil(trial_fraction * len(trials)))])
    mask = rows["trial"].isin(keep).to_numpy() & (rows.groupby("trial").cumcount().to_numpy() % frame_stride == 0)
    return {**split, "train": train[mask].tolist(),
            "trials": {**split["trials"], "train": sorted(rows["trial"][mask].unique().tolist())}}
