"""Checkpoints and training history of the tool-force model: what ``train`` writes, and whether an
existing ``last.pt`` may resume a run with the given settings, split and data."""

from __future__ import annotations

import csv
import hashlib
import json
from pathlib import Path

import numpy as np
import torch

from tactilepipe.core.atomic import atomic_path
from tactilepipe.core.errors import InputError, TactilepipeError
from tactilepipe.tool.model.network import PAPER_WIDTH
from tactilepipe.tool.model.train_config import TrainConfig
from tactilepipe.tool.model.variants import NAMED_ARCHITECTURES

CHECKPOINT_FORMAT = "tactilepipe.tool.train/1"   # a file format tag, not a module path: kept so older checkpoints load
HISTORY_COLUMNS = ["epoch", "train_loss", "val_loss", "val_mae_n", "lr", "epoch_s", "wall_s"]
# Config fields a resumed run may change; every other field must match the checkpoint.
RESUMABLE_CHANGES = {"max_epochs", "patience", "device", "amp", "num_threads"}


def split_fingerprint(split: dict) -> str:
    key = {"train": [int(i) for i in split["train"]], "validation": [int(i) for i in split["validation"]],
           "label_stats": split["label_stats"]}
    return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:16]


def data_fingerprint(data) -> str:
    """Labels and a strided sample of the frames: a rebuilt dataset with other images or labels
    must not resume a run trained on the old one."""
    h = hashlib.sha256(np.ascontiguousarray(getattr(data, "labels", np.zeros(0))).tobytes())
    frames = getattr(data, "frames", None)
    if frames is not None and len(frames):
        h.update(repr(tuple(frames.shape)).encode())
        h.update(np.ascontiguousarray(frames[:: max(1, len(frames) // 64)]).tobytes())
    return h.hexdigest()[:16]


def nonfinite_tensor(state: dict) -> tuple[str, int, int] | None:
    """(name, non-finite count, size) of the first floating-point tensor of a state dict holding a
    NaN or an infinity; None when every value is finite."""
    for name, value in state.items():
        if torch.is_tensor(value) and value.is_floating_point():
            bad = int((~torch.isfinite(value)).sum())
            if bad:
                return name, bad, value.numel()
    return None


def check_finite_weights(state: dict, path) -> None:
    """Refuse a checkpoint whose weights hold NaN or inf: a model that diverged (or a damaged file)
    estimates NaN for every input, which would otherwise be printed as estimates."""
    bad = nonfinite_tensor(state)
    if bad:
        name, count, size = bad
        raise InputError(path, f"weights: tensor '{name}' holds {count} non-finite value(s) (NaN or inf) of {size}: "
                               f"the model diverged or the file is damaged; not loaded")


def save_checkpoint(obj: dict, path: Path) -> None:
    """Write ``obj`` atomically; weights holding NaN or inf are refused, never written (a resumed
    or evaluated run would take them for a model)."""
    bad = nonfinite_tensor(obj.get("model") or {})
    if bad:
        name, count, size = bad
        raise TactilepipeError(f"{path}: not written: the trained weights diverged, tensor '{name}' holds {count} "
                               f"non-finite value(s) (NaN or inf) of {size} (epoch {obj.get('meta', {}).get('epoch')}); "
                               f"a lower tool_train.lr may train")
    # through an open file: given a path, torch.save names the archive's folder after the file, here the
    # temporary's random name, so the same weights would give other bytes on every run
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        torch.save(obj, f)


def write_history(path: Path, history: list[dict]) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=HISTORY_COLUMNS)
            w.writeheader()
            w.writerows(history)


def load_checkpoint(path: Path, raw=None) -> dict:
    """Our checkpoint at ``path`` (``raw``: its already loaded contents)."""
    if raw is None:
        from tactilepipe.tool.model.public_weights import read_state
        raw = read_state(path)
    if not isinstance(raw, dict) or raw.get("format") != CHECKPOINT_FORMAT:
        raise InputError(path, f"not a tool-model checkpoint (expected format {CHECKPOINT_FORMAT}, or the public "
                               f"code's state dict)")
    if isinstance(raw.get("model"), dict):
        check_finite_weights(raw["model"], path)
    return raw


# settings a checkpoint may not record, because it was written before they existed: the only
# value each had then (sigmoid-gated GAMs, the paper's width, the libraries' own kernels)
UNRECORDED = {"gam_channel_gate": "sigmoid", "width": PAPER_WIDTH, "kernels": "native"}


def settings_diff(ckpt: dict, cfg: TrainConfig, split: dict, data) -> dict:
    """Settings of ``cfg``/``split``/``data`` that differ from the checkpoint's (empty: it may resume)."""
    old = {"lr_schedule": "constant", **UNRECORDED, **ckpt["config"]}     # before the schedule: constant
    if old.get("architecture") is None:           # recorded by name only: the name's first definition
        named = NAMED_ARCHITECTURES.get(old.get("variant"))
        old["architecture"] = named.as_dict() if named else None
    resumable = RESUMABLE_CHANGES - ({"max_epochs"} if cfg.lr_schedule == "cosine" else set())   # it sets the decay
    diff = {k: (old.get(k), v) for k, v in cfg.model_dump().items() if k not in resumable and old.get(k) != v}
    if ckpt["meta"].get("split_fingerprint") != split_fingerprint(split):
        diff["split"] = ("another split", "this split")
    if ckpt["meta"].get("data_fingerprint") != data_fingerprint(data):
        diff["data"] = ("another dataset", "this dataset")
    return diff


def stale_checkpoint_reason(last_path: str | Path, cfg: TrainConfig, split: dict, data) -> str | None:
    """Why ``last_path`` cannot resume a run with these settings (None: it can, or it does not exist).
    A workflow uses this to start again after a settings change instead of failing."""
    if not Path(last_path).exists():
        return None
    try:
        ckpt = load_checkpoint(Path(last_path))
    except InputError as exc:
        return str(exc)
    diff = settings_diff(ckpt, cfg, split, data)
    return f"made with different settings {diff}" if diff else None
