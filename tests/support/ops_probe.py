"""Every op of the tool model's portable training path, with the sha256 of each op's outputs.

Run as a script (``python ops_probe.py --widths 32,64``), in a process of its own, because the
portable kernels must be chosen before torch loads. It prints one JSON object:
``{"capability": ..., "ops": [[label, sha256], ...], "unpinned": [[label, sha256], ...], "cpu_s": ...}``.

What runs is the trainer's own code, not a copy of it: ``build_model`` (so the initialisation's
``normal_`` and ``zero_`` are in it), one training step as ``train`` takes it (channels-last
input, the scheduled learning rate, the L1 loss, backward, ``make_optimizer``'s fused Adam step),
the BatchNorm recalibration forward and the validation forward (eval mode), and ``predict``'s
forward of one frame pair. A dispatch mode sees every ATen op each of
them runs, with the real sizes: the default scale's 16 px input and batch, at each width asked
for. Each op's outputs, and the tensors it writes in place (``relu_``, ``_fused_adam_``), are
hashed in the order the ops ran; an op whose result depends on the CPU shows up as the first label
whose hash differs between two CPUs.

``--unpinned-sqrt`` adds entries that the project's path does not run: Adam's update written with
``torch.sqrt`` (a library routine that is not correctly rounded, whose bytes depend on the vendor's
code path), on a large tensor. The tests point the comparison at them to show that it can fail.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import struct
import time


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--widths", default="32,64")
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--image-size", type=int, default=16)
    ap.add_argument("--depth", type=int, default=18)
    ap.add_argument("--variant", default="full")
    ap.add_argument("--unpinned-sqrt", action="store_true")
    args = ap.parse_args()

    from tactilepipe.tool.model.kernels import use_kernels
    kernels = use_kernels("portable")                     # before torch loads
    import numpy as np
    import torch
    from torch.utils._python_dispatch import TorchDispatchMode
    from torch.utils._pytree import tree_flatten

    from tactilepipe.tool.model.network import build_model
    from tactilepipe.tool.model.train import (_use_deterministic_algorithms, make_optimizer, scheduled_lr,
                                              to_input)
    from tactilepipe.tool.model.train_config import TrainConfig

    skipped = {"empty", "empty_like", "empty_strided", "new_empty", "new_empty_strided"}   # no values of their own

    def digest(values) -> str:
        h = hashlib.sha256()
        for v in values:
            if isinstance(v, torch.Tensor):
                t = v.detach().contiguous()
                h.update(f"{t.dtype}{tuple(t.shape)}".encode())
                h.update(t.numpy().tobytes())
            elif isinstance(v, float):
                h.update(struct.pack("<d", v))
            elif isinstance(v, (int, bool)):
                h.update(str(v).encode())
        return h.hexdigest()

    class Hasher(TorchDispatchMode):
        def __init__(self):
            super().__init__()
            self.log, self.phase = [], ""

        def __torch_dispatch__(self, func, types, args=(), kwargs=None):
            kwargs = kwargs or {}
            out = func(*args, **kwargs)
            if func.__name__.split(".")[0] in skipped:
                return out
            written = [a for a, s in zip(args, func._schema.arguments) if s.alias_info and s.alias_info.is_write]
            written += [kwargs[s.name] for s in func._schema.arguments
                        if s.name in kwargs and s.alias_info and s.alias_info.is_write]
            self.log.append([f"{self.phase} {len(self.log):05d} {func}",
                             digest(tree_flatten(out)[0] + tree_flatten(written)[0])])
            return out

    torch.set_num_threads(1)
    _use_deterministic_algorithms(True, warn_only=False)
    rng = np.random.default_rng(2026)
    hasher = Hasher()
    for width in (int(w) for w in args.widths.split(",")):
        s, b = args.image_size, args.batch
        # frames as the data set stores them (8-bit levels / 255), labels on the min-max scale
        x = torch.from_numpy(rng.integers(0, 256, (b, 4, s, s)).astype(np.float32) / np.float32(255))
        y = torch.from_numpy(rng.integers(0, 1 << 16, b).astype(np.float32) / np.float32(1 << 16))
        cfg = TrainConfig(variant=args.variant, depth=args.depth, image_size=s, lr=2e-4, lr_schedule="cosine",
                          batch_size=b, max_epochs=8, patience=3, normalise="minmax", seed=2026, device="cpu",
                          amp=True, num_threads=1, max_train_batches_per_epoch=0, bn_recalibration_batches=20,
                          gam_channel_gate="sigmoid", width=width, kernels="portable")
        with hasher:
            hasher.phase = f"w{width} init"
            torch.manual_seed(cfg.seed)
            model = build_model(cfg.variant, cfg.depth, s, cfg.gam_channel_gate, width)
            model = model.to(memory_format=torch.channels_last)
            opt = make_optimizer(model, cfg.lr)
            hasher.phase = f"w{width} step"
            model.train()
            for group in opt.param_groups:
                group["lr"] = scheduled_lr(cfg, 1, 100)
            pred = model(to_input(x, torch.device("cpu"), True))
            loss = torch.nn.functional.l1_loss(pred.float(), y)
            loss.item()
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()                   # Adam's square root of moments that are not zero, as every step
            with torch.no_grad():
                hasher.phase = f"w{width} bn-recalibration"
                for m in model.modules():
                    if isinstance(m, torch.nn.modules.batchnorm._BatchNorm):
                        m.reset_running_stats()
                        m.momentum = None
                        m.train()
                model(to_input(x, torch.device("cpu"), True))
                model.eval()
                hasher.phase = f"w{width} validation"
                model(to_input(x, torch.device("cpu"), True))
                hasher.phase = f"w{width} predict"
                model(to_input(x[:1], torch.device("cpu"), True))

    unpinned = []
    if args.unpinned_sqrt:
        # Adam's update as the unfused optimiser writes it, on a tensor as large as a layer's moments
        n = 1 << 20
        m = torch.from_numpy((rng.integers(-(1 << 20), 1 << 20, n) / float(1 << 30)).astype(np.float32))
        v = torch.from_numpy((rng.integers(1, 1 << 24, n) / float(1 << 40)).astype(np.float32))
        p = torch.from_numpy((rng.integers(-(1 << 20), 1 << 20, n) / float(1 << 20)).astype(np.float32))
        denom = torch.sqrt(v / (1 - 0.999 ** 2)) + 1e-8
        unpinned.append(["unpinned torch.sqrt", digest([denom])])
        unpinned.append(["unpinned Adam update with torch.sqrt", digest([p - 2e-4 / (1 - 0.9 ** 2) * m / denom])])
    print(json.dumps({"capability": kernels["aten_capability"], "layers": kernels.get("layers"), "ops": hasher.log, "unpinned": unpinned,
                      "cpu_s": time.process_time()}))


if __name__ == "__main__":
    main()
