"""A trained tool-force model at work: load a checkpoint (ours or the public code's), predict forces in
N for a set of samples, and time one forward pass."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import torch
from torch import nn

from tactilepipe.core.errors import ArgumentError, InputError
from tactilepipe.tool.model.checkpoint import UNRECORDED, check_finite_weights, load_checkpoint
from tactilepipe.tool.model.network import build_model
from tactilepipe.tool.model.train import denormalise, resolve_device, to_input, uses_channels_last
from tactilepipe.tool.model.variants import Architecture


def load_model(checkpoint_path: str | Path, device: str = "cpu", channels_last: bool = True,
               image_size: int | None = None) -> tuple[nn.Module, dict]:
    """Model of a ``best.pt`` or ``last.pt`` in eval mode, and its metadata (variant, depth,
    image_size, normalise, label_stats, label, epoch, val_loss, val_mae_n, config, ...).

    A state dict saved by the public code of study 000 (its published ``best_model_*.pth``) is
    recognised by its key names and loaded through tool/model/public_weights.py; it records neither its
    input size nor its label scaling, so ``image_size`` must be given (metadata ``label_stats``
    is then None and ``source`` "public")."""
    from tactilepipe.tool.model import public_weights
    raw = public_weights.read_state(Path(checkpoint_path))
    if public_weights.is_public_state(raw):
        if image_size is None:
            raise InputError(checkpoint_path, "a public-code checkpoint records no input size: give the image "
                                              "size to run it at")
        model, meta = public_weights.public_model(raw, image_size, Path(checkpoint_path))
        check_finite_weights(model.state_dict(), checkpoint_path)
    else:
        model, meta = _own_model(Path(checkpoint_path), raw)
    model = model.to(resolve_device(device))
    if channels_last:
        model = model.to(memory_format=torch.channels_last)
    return model.eval(), meta


def _own_model(checkpoint_path: Path, raw) -> tuple[nn.Module, dict]:
    ckpt = load_checkpoint(checkpoint_path, raw)
    meta = {**UNRECORDED, **ckpt["meta"], "config": ckpt["config"], "source": "tactilepipe"}
    try:
        # a checkpoint records its variant's architecture; one written before variants were
        # parameters records only the name, which build_model resolves (variants.NAMED_ARCHITECTURES)
        recorded = meta.get("architecture")
        arch = Architecture.from_dict(recorded) if recorded is not None else None
        model = build_model(meta["variant"], meta["depth"], meta["image_size"], meta["gam_channel_gate"], meta["width"],
                            arch)
    except ArgumentError as exc:                  # the file's metadata, not the caller's argument
        raise InputError(checkpoint_path, f"metadata: {exc}") from None
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(checkpoint_path, f"metadata: architecture {meta.get('architecture')!r} is not "
                                          f"{{'sensors': [[start, stop], ...], 'gam': bool}} ({exc!r})") from None
    try:
        model.load_state_dict(ckpt["model"])
    except RuntimeError as exc:                   # torch lists every mismatched key: the first says enough
        first = next((line.strip() for line in str(exc).splitlines()[1:] if line.strip()), str(exc))
        raise InputError(checkpoint_path, f"its weights do not fit the model its metadata describes (variant "
                                          f"{meta['variant']}, depth {meta['depth']}, width {meta['width']}): "
                                          f"{first}") from None
    return model, meta


def predict(model: nn.Module, data, idx, label_stats: dict, normalise: str, batch_size: int = 256) -> np.ndarray:
    """Denormalised forces (N) for samples ``idx`` of ``data``, in the order of ``idx``."""
    device = next(model.parameters()).device
    cl = uses_channels_last(model)
    was_training = model.training
    model.eval()
    out = []
    try:
        with torch.no_grad():
            for x, _, _ in data.batches(np.asarray(idx, int), batch_size, shuffle=False):
                out.append(model(to_input(x, device, cl)).float().cpu())
    finally:
        model.train(was_training)
    z = torch.cat(out).numpy() if out else np.zeros(0, np.float32)
    return denormalise(z.astype(np.float64), label_stats, normalise)


def latency_ms(model: nn.Module, image_size: int, n: int = 50, warmup: int = 5) -> float:
    """Median wall time (ms) of one forward pass of one frame pair (batch 1), after warm-up."""
    device = next(model.parameters()).device
    x = to_input(torch.rand(1, 4, image_size, image_size), device, uses_channels_last(model))
    was_training = model.training
    model.eval()
    times = []
    try:
        with torch.no_grad():
            for i in range(warmup + n):
                if device.type == "cuda":
                    torch.cuda.synchronize()
                t = time.perf_counter()
                model(x)
                if device.type == "cuda":
                    torch.cuda.synchronize()
                if i >= warmup:
                    times.append(time.perf_counter() - t)
    finally:
        model.train(was_training)
    return float(np.median(times) * 1000.0)
