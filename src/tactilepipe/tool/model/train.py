"""Trainer of the tool-force model (paper section IV-C), as library code.

Adam (lr 2e-4), L1 loss on normalised labels (min-max for the normal force, z-score for shear:
``TrainConfig.normalise``; the statistics are the split's ``label_stats``, taken from the
training split only), batch 64, early stopping on the validation loss. Unlike the public code it is
seeded and deterministic on CPU, validates on whole splits (per-sample means, not means over
batches), checkpoints every epoch and resumes an interrupted run to the same result.

Files written into ``out_dir`` (each atomically):

    history.csv   one row per epoch: epoch, train_loss, val_loss (normalised L1), val_mae_n (N),
                  lr, epoch_s (training + validation), wall_s (sum of epoch_s, over resumes too)
    last.pt       model, optimiser, epoch, best validation loss, RNG states, history, config
    best.pt       model of the epoch with the lowest validation loss, with its metadata

Epochs and batches are numbered from 1 in the history and in error messages. The checkpoint format
and the check of whether a ``last.pt`` may resume are in ``checkpoint.py``.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
import torch
from torch import nn
from torch.optim.adam import adam as adam_update

from tactilepipe.core.errors import ConfigError, TactilepipeError
from tactilepipe.tool.model.checkpoint import (CHECKPOINT_FORMAT, data_fingerprint, load_checkpoint, save_checkpoint,
                                               settings_diff, split_fingerprint, write_history)
from tactilepipe.tool.checks import kernels_conflict
from tactilepipe.tool.model.kernels import check_mode, require_active
from tactilepipe.tool.model.network import build_model, count_parameters
from tactilepipe.tool.model.train_config import TrainConfig
from tactilepipe.tool.model.variants import Architecture


# ----------------------------------------------------------------------------- label scaling

def normalise(y, stats: dict, mode: str):
    """Labels in N -> the scale the model is trained on."""
    if mode == "minmax":
        span = (stats["max"] - stats["min"]) or 1.0
        return (y - stats["min"]) / span
    if mode == "zscore":
        return (y - stats["mean"]) / (stats["std"] or 1.0)
    raise TactilepipeError(f"unknown label normalisation '{mode}' (minmax or zscore)")


def denormalise(z, stats: dict, mode: str):
    """Model outputs -> N (inverse of ``normalise``)."""
    if mode == "minmax":
        return z * ((stats["max"] - stats["min"]) or 1.0) + stats["min"]
    if mode == "zscore":
        return z * (stats["std"] or 1.0) + stats["mean"]
    raise TactilepipeError(f"unknown label normalisation '{mode}' (minmax or zscore)")


# ----------------------------------------------------------------------------- helpers

def resolve_device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    dev = torch.device(name)
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise TactilepipeError(f"device '{name}' requested but CUDA is not available")
    return dev


# torch.optim's Optimizer methods are wrapped so that their first call imports torch._dynamo (to
# keep them out of torch.compile graphs), and Adam.step imports it at every call: 2-5 CPU s per
# training process, more than a whole smoke-scale training, and far more under an emulated CPU.
# Nothing here runs under torch.compile, so FusedAdam uses the methods unwrapped and a step that
# calls the same functional update (the fused kernel, the same arithmetic and bytes).
_DYNAMO_WRAPPED = torch._disable_dynamo(lambda: None).__code__


class FusedAdam(torch.optim.Adam):
    """torch's Adam with ``fused=True``, without the torch.compile hooks (see above)."""
    locals().update({name: f.__wrapped__ for name, f in vars(torch.optim.Optimizer).items()
                     if getattr(f, "__code__", None) is _DYNAMO_WRAPPED})

    @torch.no_grad()
    def step(self, closure=None):
        if closure is not None:
            raise NotImplementedError("FusedAdam.step takes no closure")
        for group in self.param_groups:
            params, grads, avgs, sqs, max_sqs, steps = [], [], [], [], [], []
            has_complex = self._init_group(group, params, grads, avgs, sqs, max_sqs, steps)
            beta1, beta2 = group["betas"]
            # grad_scale / found_inf: set by a GradScaler (mixed precision on CUDA) for a fused step
            adam_update(params, grads, avgs, sqs, max_sqs, steps, amsgrad=group["amsgrad"], has_complex=has_complex,
                        beta1=beta1, beta2=beta2, lr=group["lr"], weight_decay=group["weight_decay"], eps=group["eps"],
                        maximize=group["maximize"], foreach=group["foreach"], capturable=group["capturable"],
                        differentiable=group["differentiable"], fused=group["fused"],
                        grad_scale=getattr(self, "grad_scale", None), found_inf=getattr(self, "found_inf", None),
                        decoupled_weight_decay=group["decoupled_weight_decay"])


def make_optimizer(model: nn.Module, lr: float) -> FusedAdam:
    # The fused kernel updates all ~24 M parameters in one pass: the same Adam arithmetic, 5-18 %
    # more frame pairs/s on 2 CPU cores than the per-tensor loop (the update is ~12 % of a step).
    return FusedAdam(model.parameters(), lr=lr, fused=True)


def scheduled_lr(cfg: TrainConfig, step: int, total_steps: int) -> float:
    """Learning rate of training step ``step`` (0-based) of ``total_steps``. The paper keeps Adam at
    2e-4 for up to 300 epochs; a CPU budget of a few epochs ends while that constant rate still
    moves the weights far from epoch to epoch (at 16 px the validation loss went 0.019 -> 0.026 ->
    0.021 over epochs 6-8), so the short scales decay it to 0 along a half cosine: the last epochs
    settle (0.019, 0.020, 0.020), and which epoch is kept matters less."""
    if cfg.lr_schedule == "cosine":
        return cfg.lr * 0.5 * (1.0 + math.cos(math.pi * min(step, total_steps) / max(total_steps, 1)))
    return cfg.lr


def uses_channels_last(model: nn.Module) -> bool:
    # a conv weight whose strides tell the two formats apart (not 1 input channel or a 1x1 kernel)
    w = next((p for p in model.parameters() if p.ndim == 4 and p.shape[1] > 1 and p.shape[2] > 1), None)
    return w is not None and w.is_contiguous(memory_format=torch.channels_last) and not w.is_contiguous()


def to_input(x: torch.Tensor, device: torch.device, channels_last: bool) -> torch.Tensor:
    x = x.to(device, non_blocking=True)
    return x.contiguous(memory_format=torch.channels_last) if channels_last else x


def _epoch_seed(seed: int, epoch: int) -> int:
    return int(np.random.SeedSequence([seed, epoch]).generate_state(1)[0])


def _check_data(data, split: dict, cfg: TrainConfig) -> tuple[np.ndarray, np.ndarray]:
    train_idx, val_idx = np.asarray(split["train"], int), np.asarray(split["validation"], int)
    if len(train_idx) < 2 or len(val_idx) < 1:
        raise TactilepipeError(f"split '{split.get('name', '?')}' has {len(train_idx)} training and "
                               f"{len(val_idx)} validation samples: need at least 2 and 1")
    if cfg.batch_size < 2:
        raise TactilepipeError(f"batch_size {cfg.batch_size}: BatchNorm needs at least 2 samples per batch")
    n = len(data)
    if max(train_idx.max(), val_idx.max()) >= n or min(train_idx.min(), val_idx.min()) < 0:
        raise TactilepipeError(f"split indices out of range for a dataset of {n} samples")
    frames = getattr(data, "frames", None)
    if frames is not None and tuple(frames.shape[-2:]) != (cfg.image_size, cfg.image_size):
        raise TactilepipeError(f"dataset frames are {tuple(frames.shape[-2:])} px but the model is configured "
                               f"for image_size {cfg.image_size}")
    normalise(0.0, split["label_stats"], cfg.normalise)   # validates the mode
    check_mode(cfg.kernels)          # the kernels against threads and device: train(), once the device is known
    return train_idx, val_idx


def _summary(state: dict, meta: dict, device: torch.device, resumed_from: int) -> dict:
    hist = state["history"]
    best = next((h for h in hist if h["epoch"] == state["best_epoch"]), None)
    return {"epochs_run": len(hist), "best_epoch": state["best_epoch"],
            "best_val_loss": state["best_val_loss"],
            "best_val_mae_n": best["val_mae_n"] if best else float("nan"),
            "train_wall_s": hist[-1]["wall_s"] if hist else 0.0,
            "early_stopped": state["early_stopped"], "resumed_from_epoch": resumed_from,
            "parameters": meta["parameters"], "device": str(device),
            "variant": meta["variant"], "depth": meta["depth"], "image_size": meta["image_size"]}


# ----------------------------------------------------------------------------- training

def train(data, split: dict, cfg: TrainConfig, out_dir: str | Path, progress: bool = True) -> dict:
    """Train (or resume from ``out_dir/last.pt``) and return a summary dict.

    ``data`` is a ``ToolFrames`` (or anything with its ``batches``/``__len__``), ``split`` a split
    dict of ``tool.splits.make_split``. On CPU the run is deterministic for a given seed and thread
    count; a run resumed after an interruption ends with the same weights as an uninterrupted one.
    """
    from tqdm import tqdm

    out_dir = Path(out_dir)
    train_idx, val_idx = _check_data(data, split, cfg)
    # portable kernels are CPU kernels: "auto" takes the CPU even where CUDA is present
    device = resolve_device("cpu" if cfg.kernels == "portable" and cfg.device == "auto" else cfg.device)
    if why := kernels_conflict("tool_train", cfg.kernels, cfg.num_threads, device.type):
        raise ConfigError(why)
    use_amp = bool(cfg.amp) and device.type == "cuda"
    stats = split["label_stats"]
    meta = {"variant": cfg.variant, "architecture": cfg.architecture, "depth": cfg.depth, "image_size": cfg.image_size,
            "gam_channel_gate": cfg.gam_channel_gate, "width": cfg.width, "normalise": cfg.normalise, "label_stats": dict(stats), "label": split.get("label"),
            "split": split.get("name"), "split_fingerprint": split_fingerprint(split),
            "data_fingerprint": data_fingerprint(data), "frame_orientation": getattr(data, "orientation", None)}

    saved = (torch.get_num_threads(), torch.are_deterministic_algorithms_enabled(),
             torch.is_deterministic_algorithms_warn_only_enabled())
    try:
        if cfg.num_threads:
            torch.set_num_threads(int(cfg.num_threads))
        kernels = require_active(cfg.kernels) if device.type == "cpu" else {"mode": cfg.kernels}
        _use_deterministic_algorithms(True, warn_only=device.type != "cpu")
        torch.manual_seed(cfg.seed)
        model = build_model(cfg.variant, cfg.depth, cfg.image_size, cfg.gam_channel_gate, cfg.width,
                            Architecture.from_dict(cfg.architecture)).to(device)
        if cfg.channels_last:
            model = model.to(memory_format=torch.channels_last)
        meta["parameters"] = count_parameters(model)
        opt = make_optimizer(model, cfg.lr)
        scaler = torch.amp.GradScaler("cuda", enabled=use_amp)
        state = {"epoch": 0, "best_val_loss": math.inf, "best_epoch": 0, "bad_epochs": 0,
                 "early_stopped": False, "history": []}

        last_path, best_path = out_dir / "last.pt", out_dir / "best.pt"
        resumed_from = 0
        if last_path.exists():
            ckpt = load_checkpoint(last_path)
            diff = settings_diff(ckpt, cfg, split, data)
            if diff:
                raise TactilepipeError(f"{last_path}: made with different settings {diff}; "
                                       f"delete it or train into another directory")
            model.load_state_dict(ckpt["model"])
            opt.load_state_dict(ckpt["optimizer"])
            scaler.load_state_dict(ckpt["scaler"])
            state = {k: ckpt[k] for k in state}
            torch.set_rng_state(ckpt["rng"]["torch"])
            if device.type == "cuda" and ckpt["rng"].get("cuda"):
                torch.cuda.set_rng_state_all(ckpt["rng"]["cuda"])
            resumed_from = state["epoch"]
            write_history(out_dir / "history.csv", state["history"])

        n_batches = math.ceil(len(train_idx) / cfg.batch_size)
        if cfg.max_train_batches_per_epoch:
            n_batches = min(n_batches, int(cfg.max_train_batches_per_epoch))
        for epoch in range(state["epoch"] + 1, cfg.max_epochs + 1):
            if state["early_stopped"]:
                break
            t0 = time.perf_counter()
            model.train()
            total, count = 0.0, 0
            # the bar only on a terminal (disable=None): in a log file it would be carriage returns
            bar = tqdm(total=n_batches, desc=f"epoch {epoch}/{cfg.max_epochs}", unit="batch",
                       file=sys.stderr, disable=None if progress else True, leave=False)
            batches = data.batches(train_idx, cfg.batch_size, shuffle=True, seed=_epoch_seed(cfg.seed, epoch))
            for b, (x, y, part) in enumerate(batches, start=1):
                if b > n_batches:
                    break
                if len(y) < 2:            # BatchNorm on 1x1 maps cannot train on a single sample
                    bar.update(1)
                    continue
                for group in opt.param_groups:
                    group["lr"] = scheduled_lr(cfg, (epoch - 1) * n_batches + b - 1, cfg.max_epochs * n_batches)
                x = to_input(x, device, cfg.channels_last)
                target = normalise(y.to(device), stats, cfg.normalise)
                with torch.autocast(device.type, enabled=use_amp):
                    pred = model(x)
                loss = nn.functional.l1_loss(pred.float(), target)
                value = loss.item()
                if not math.isfinite(value):
                    raise TactilepipeError(_bad_loss("training", value, epoch, b, y, part))
                opt.zero_grad(set_to_none=True)
                scaler.scale(loss).backward()
                scaler.step(opt)
                scaler.update()
                total += value * len(y)
                count += len(y)
                bar.set_postfix(loss=f"{value:.4f}", refresh=False)
                bar.update(1)
            bar.close()
            train_loss = total / max(count, 1)
            if cfg.bn_recalibration_batches:
                recalibrate_batchnorm(model, data, train_idx, cfg, device, seed=_epoch_seed(cfg.seed + 7919, epoch))   # its own draw
            val_loss, val_mae = _validate(model, data, val_idx, cfg, stats, device, use_amp, epoch)
            epoch_s = time.perf_counter() - t0
            prev_wall = state["history"][-1]["wall_s"] if state["history"] else 0.0
            state["history"].append({"epoch": epoch, "train_loss": train_loss, "val_loss": val_loss,
                                     "val_mae_n": val_mae, "lr": opt.param_groups[0]["lr"],
                                     "epoch_s": epoch_s, "wall_s": prev_wall + epoch_s})
            state["epoch"] = epoch
            if val_loss < state["best_val_loss"]:
                state.update(best_val_loss=val_loss, best_epoch=epoch, bad_epochs=0)
                save_checkpoint({"format": CHECKPOINT_FORMAT, "model": model.state_dict(), "config": cfg.model_dump(),
                       "meta": {**meta, "epoch": epoch, "val_loss": val_loss, "val_mae_n": val_mae}}, best_path)
            else:
                state["bad_epochs"] += 1
            if cfg.patience and state["bad_epochs"] >= cfg.patience:
                state["early_stopped"] = True
            rng = {"torch": torch.get_rng_state(),
                   "cuda": torch.cuda.get_rng_state_all() if device.type == "cuda" else []}
            save_checkpoint({"format": CHECKPOINT_FORMAT, "model": model.state_dict(), "optimizer": opt.state_dict(),
                   "scaler": scaler.state_dict(), "rng": rng, "config": cfg.model_dump(),
                   "meta": {**meta, "epoch": epoch, "val_loss": val_loss, "val_mae_n": val_mae}, **state}, last_path)
            write_history(out_dir / "history.csv", state["history"])
            # one line per epoch whatever stderr is (a job's log under Snakemake): what a long run is doing
            tqdm.write(epoch_line(state["history"][-1], cfg.max_epochs), file=sys.stderr)
            sys.stderr.flush()
        return {**_summary(state, meta, device, resumed_from), "kernels": kernels}
    finally:
        torch.set_num_threads(saved[0])
        _use_deterministic_algorithms(saved[1], warn_only=saved[2])


def epoch_line(row: dict, max_epochs: int) -> str:
    """The log line of one epoch (a row of history.csv): losses, validation MAE, time so far."""
    return (f"epoch {row['epoch']}/{max_epochs}: train loss {row['train_loss']:.4f}, val loss {row['val_loss']:.4f}, "
            f"val MAE {row['val_mae_n']:.3f} N, {row['epoch_s']:.1f} s (elapsed {row['wall_s']:.1f} s)")


def _use_deterministic_algorithms(mode: bool, warn_only: bool) -> None:
    """torch.use_deterministic_algorithms without its side effect: it also sets the flag of
    torch.compile's back end, and importing that back end took 3.8 s of each smoke training job
    (torch 2.13, cProfile). Nothing here compiles, so only the eager-mode flag matters."""
    torch._C._set_deterministic_algorithms(mode, warn_only=warn_only)


@torch.no_grad()
def recalibrate_batchnorm(model: nn.Module, data, idx, cfg: TrainConfig, device: torch.device, seed: int) -> None:
    """Re-estimate every BatchNorm's statistics from ``cfg.bn_recalibration_batches`` training
    batches with the current weights (equal-weight average; dropout off), as "precise BN" does.

    Why: the running averages (momentum 0.1) trail weights that move fast early in training, and
    this network normalises 1x1 and 2x2 maps, where batch statistics are all it sees. Measured on
    the default data after 100 steps at 32 px: R² on the training frames 0.23 with the running
    averages, 0.80 after recalibration; the validation loss that picks the best epoch was as wrong.
    """
    bns = [m for m in model.modules() if isinstance(m, nn.modules.batchnorm._BatchNorm)]
    if not bns:
        return
    momenta = [m.momentum for m in bns]
    model.eval()
    for m in bns:
        m.reset_running_stats()
        m.momentum = None                         # cumulative average over the batches below
        m.train()
    try:
        batches = data.batches(idx, cfg.batch_size, shuffle=True, seed=seed)
        for b, (x, _, _) in enumerate(batches):
            if b >= cfg.bn_recalibration_batches:
                break
            if len(x) >= 2:
                model(to_input(x, device, cfg.channels_last))
    finally:
        for m, momentum in zip(bns, momenta):
            m.momentum = momentum
        model.eval()


def _bad_loss(phase: str, value: float, epoch: int, batch: int, y: torch.Tensor, part) -> str:
    bad = np.asarray(part)[~np.isfinite(y.numpy())]
    cause = (f"non-finite labels at sample indices {bad[:10].tolist()}" if len(bad)
             else "labels are finite (diverging model or bad inputs)")
    return f"non-finite {phase} loss ({value}) at epoch {epoch}, batch {batch}: {cause}"


@torch.no_grad()
def _validate(model, data, idx, cfg, stats, device, use_amp, epoch) -> tuple[float, float]:
    model.eval()
    abs_norm, abs_n, count = 0.0, 0.0, 0
    for b, (x, y, part) in enumerate(data.batches(idx, cfg.batch_size, shuffle=False), start=1):
        x = to_input(x, device, cfg.channels_last)
        with torch.autocast(device.type, enabled=use_amp):
            pred = model(x).float()
        err = (pred - normalise(y.to(device), stats, cfg.normalise)).abs().sum().item()
        if not math.isfinite(err):
            raise TactilepipeError(_bad_loss("validation", err, epoch, b, y, part))
        abs_norm += err
        abs_n += (denormalise(pred, stats, cfg.normalise) - y.to(device)).abs().sum().item()
        count += len(y)
    return abs_norm / count, abs_n / count
