"""Fixed-order kernels against native and MKL-portable ones, layer by layer and for a training step.

Three kinds of process, each on one thread: ``native`` (oneDNN, MKL's own dispatch, ATen's widest
build), ``portable`` (the pins of tool/model/kernels.py: no oneDNN, MKL COMPATIBLE, ATen AVX2) and
``fixed`` (the same pins, with the network's convolutions and linear layers on the fixed-order
kernels of tool/model/fixed_order.py). For every distinct convolution and linear layer of the full
model (forward and backward at its input size, batch and width, as the network runs it: trimmed
taps, channels-last) and for a whole training step (forward, backward, fused Adam), it prints the
time per call and each mode's speed relative to native.

The machine may be shared: the modes run in turn, round after round (--rounds), each in its own
process, and each figure is the median over rounds of the CPU time of the process (not wall time),
so other jobs on the machine cost a mode little. Read the ratios, not the absolute times.

Usage: python benchmarks/bench_gemm.py [--width 64] [--rounds 3] [--steps 6] [--reps 5] [--small]
(--small: width 8, batch 8, one round: a quick check that the script runs).
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import statistics
import time
from pathlib import Path

from tactilepipe.core.config import load_params

REPO = Path(__file__).resolve().parents[1]
MODES = ("native", "portable", "fixed")


def _layers(model, x) -> list[tuple]:
    """(kind, spec, count) of every distinct conv/linear call of one forward pass of ``model``."""
    import torch
    from torch import nn

    from tactilepipe.tool.model.network import TrimmedConv2d, _unused_taps
    seen: dict[tuple, int] = {}

    def hook(mod, inp, out):
        x = inp[0]
        if isinstance(mod, nn.Conv2d):
            kh, (ph, sh) = mod.kernel_size[0], (mod.padding[0], mod.stride[0])
            th = _unused_taps(kh, ph, sh, x.shape[-2]) if isinstance(mod, TrimmedConv2d) else 0
            key = ("conv", (x.shape[0], x.shape[1], x.shape[2], mod.out_channels, kh - 2 * th, sh, ph - th,
                            mod.bias is not None))
        else:
            key = ("linear", (x.numel() // x.shape[-1], x.shape[-1], mod.out_features))
        seen[key] = seen.get(key, 0) + 1

    handles = [m.register_forward_hook(hook) for m in model.modules() if isinstance(m, (nn.Conv2d, nn.Linear))]
    with torch.no_grad():
        model(x)
    for h in handles:
        h.remove()
    return [(kind, spec, n) for (kind, spec), n in seen.items()]


def _flops(kind: str, spec: tuple) -> int:
    """Multiply-adds x 2 of one forward call."""
    if kind == "conv":
        b, c, h, n, k, s, p, _ = spec
        ho = (h + 2 * p - k) // s + 1
        return 2 * b * ho * ho * n * c * k * k
    m, k, n = spec
    return 2 * m * k * n


def _cpu_per_call(fn, reps: int) -> float:
    fn()                                         # warm-up (and the library build, the first time)
    t = time.process_time()
    for _ in range(reps):
        fn()
    return (time.process_time() - t) / reps


def _worker(args: tuple) -> dict:
    mode, tt, width, batch, steps, reps = args
    from tactilepipe.tool.model.kernels import use_kernels
    use_kernels("native" if mode == "native" else "portable")     # before torch loads
    import torch
    from torch import nn

    from tactilepipe.tool.model import fixed_order
    from tactilepipe.tool.model.network import build_model
    from tactilepipe.tool.model.train import make_optimizer
    torch.set_num_threads(1)
    fixed_order.set_enabled(mode == "fixed")
    size, cl = tt["image_size"], torch.channels_last
    torch.manual_seed(0)
    model = build_model("full", tt["depth"], size, tt["gam_channel_gate"], width).to(memory_format=cl)
    x = torch.rand(batch, 4, size, size).contiguous(memory_format=cl)
    out = {}
    for kind, spec, count in _layers(model, x):
        if kind == "conv":
            b, c, h, n, k, s, p, bias = spec
            inp = torch.randn(b, c, h, h).contiguous(memory_format=cl).requires_grad_(c > 4)
            w = torch.randn(n, c, k, k).contiguous(memory_format=cl).requires_grad_()
            bv = torch.randn(n, requires_grad=True) if bias else None
            call = lambda: fixed_order.conv2d(inp, w, bv, (s, s), (p, p))          # noqa: E731
        else:
            m, kk, n = spec
            inp, w, bv = torch.randn(m, kk, requires_grad=True), torch.randn(n, kk, requires_grad=True), \
                torch.randn(n, requires_grad=True)
            call = lambda: fixed_order.linear(inp, w, bv)                          # noqa: E731
        y = call()
        gy = torch.randn_like(y)

        def fwd_bwd():
            call().backward(gy)
        out[(kind, spec, count)] = _cpu_per_call(fwd_bwd, reps)
    opt = make_optimizer(model, 2e-4)
    target = torch.rand(batch)
    model.train()

    def step():
        opt.zero_grad(set_to_none=True)
        nn.functional.l1_loss(model(x), target).backward()
        opt.step()
    out["step"] = _cpu_per_call(step, steps)
    return out


def _label(kind: str, spec: tuple) -> str:
    if kind == "conv":
        b, c, h, n, k, s, p, _ = spec
        return f"conv {c}->{n} {k}x{k}/{s} on {h}x{h}"
    m, k, n = spec
    return f"linear {k}->{n} x{m}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=64)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--steps", type=int, default=6)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--small", action="store_true")
    args = ap.parse_args()
    tt = load_params(REPO / "params.yaml")["tool_train"]
    width, batch, rounds = (8, 8, 1) if args.small else (args.width, tt["batch_size"], args.rounds)
    steps, reps = (1, 1) if args.small else (args.steps, args.reps)
    ctx = mp.get_context("spawn")
    runs = {m: [] for m in MODES}
    for _ in range(rounds):
        for mode in MODES:
            with ctx.Pool(1) as pool:
                runs[mode].append(pool.map(_worker, [(mode, tt, width, batch, steps, reps)])[0])
    med = {m: {key: statistics.median(r[key] for r in runs[m]) for key in runs[m][0]} for m in MODES}
    print(f"full model, depth {tt['depth']}, {tt['image_size']} px, batch {batch}, width {width}, one thread; "
          f"CPU ms per call (forward + backward), median of {rounds} round(s); speed relative to native")
    print(f"{'layer':34s} {'calls':>5s} {'GFLOP':>6s} {'native':>8s} {'portable':>9s} {'fixed':>8s} "
          f"{'portable/native':>16s} {'fixed/native':>13s}")
    total = {m: 0.0 for m in MODES}
    for key in med["native"]:
        if key == "step":
            continue
        kind, spec, count = key
        t = {m: med[m][key] for m in MODES}
        for m in MODES:
            total[m] += t[m] * count
        print(f"{_label(kind, spec):34s} {count:5d} {3 * _flops(kind, spec) * count / 1e9:6.2f} "
              f"{t['native'] * 1e3:8.2f} {t['portable'] * 1e3:9.2f} {t['fixed'] * 1e3:8.2f} "
              f"{t['native'] / t['portable']:16.2f} {t['native'] / t['fixed']:13.2f}")
    print(f"{'all conv + linear layers':34s} {'':5s} {'':6s} {total['native'] * 1e3:8.1f} "
          f"{total['portable'] * 1e3:9.1f} {total['fixed'] * 1e3:8.1f} "
          f"{total['native'] / total['portable']:16.2f} {total['native'] / total['fixed']:13.2f}")
    s = {m: med[m]["step"] for m in MODES}
    print(f"{'training step (fwd, bwd, Adam)':34s} {'':5s} {'':6s} {s['native'] * 1e3:8.1f} "
          f"{s['portable'] * 1e3:9.1f} {s['fixed'] * 1e3:8.1f} "
          f"{s['native'] / s['portable']:16.2f} {s['native'] / s['fixed']:13.2f}")
    print("frame pairs/s (CPU time): " + ", ".join(f"{m} {batch / s[m]:.0f}" for m in MODES))


if __name__ == "__main__":
    main()
