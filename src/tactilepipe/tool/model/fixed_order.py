"""Fixed-order matrix products, convolutions and linear layers: bytes that no CPU can change.

Each output element of ``gemm`` is one chain of fused multiply-adds over the reduction index, in
increasing order (fixed_order_c.py). The vector lanes and the register tiles split only the
output elements, so the result depends neither on the blocking nor on the vector width, and FMA is
correctly rounded: every x86-64 CPU with AVX2 and FMA gives the same bits, at AVX2 speed. MKL's
COMPATIBLE branch, the library path that also gives the same bits on Intel and AMD, is SSE2 code
without FMA (benchmarks/record.md, "Fixed-order kernels per layer", has both measured).

A convolution is an im2col and one ``gemm`` forward, and two more for its gradients: the input's
(followed by a col2im that adds each tap's share in a fixed tap order, plain IEEE additions) and the
weight's, whose chains run over every output pixel of the batch in order. A bias' gradient is the
product with a row of ones, so it too is one chain (computed as the additions it amounts to). The
im2col and col2im are C loops too: torch's strided copies and per-tap additions took as long as the
products they feed (benchmarks/record.md). ``conv2d`` and ``linear`` take these paths
while ``set_enabled(True)`` is in force (kernels.py turns it on with the portable kernels) and
call torch's own otherwise.

The C source is compiled with the system's C compiler on first use, into a cache keyed by the
hash of the source and the flags (``TACTILEPIPE_KERNEL_CACHE``, else ~/.cache/tactilepipe); the
compiler reads a copy written there, so a stage reads no file of the project for it.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import torch
from torch.nn import functional as F

from tactilepipe.core.errors import TactilepipeError
from tactilepipe.tool.model.fixed_order_c import SOURCE
# No -ffast-math, no contraction: the source's fma calls are the only fused operations.
CFLAGS = ("-O2", "-mavx2", "-mfma", "-ffp-contract=off", "-fno-fast-math", "-fPIC", "-shared")
_lib = None
_enabled = False


def set_enabled(on: bool) -> None:
    """Route the network's convolutions and linear layers through the fixed-order kernels (True)
    or torch's own (False). Building the library happens here, so a missing compiler is reported
    when the kernels are chosen, not in the middle of a training step."""
    global _enabled
    if on:
        _library()
    _enabled = bool(on)


def enabled() -> bool:
    return _enabled


def _cache_dir() -> Path:
    return Path(os.environ.get("TACTILEPIPE_KERNEL_CACHE") or Path.home() / ".cache" / "tactilepipe")


def library_path() -> Path:
    """Where the compiled library of this source and these flags lives (built or not)."""
    digest = hashlib.sha256(SOURCE.encode() + b"\0" + " ".join(CFLAGS).encode()).hexdigest()[:16]
    return _cache_dir() / f"fixed_order_gemm-{digest}.so"


def build_library() -> Path:
    """Compile the C source unless this source's library is cached already; return its path."""
    path = library_path()
    if path.exists():
        return path
    cc = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    if not cc:
        raise TactilepipeError("the portable kernels compile a small C library on first use, and no C compiler "
                               "was found (install gcc, or set CC); or use kernels: native")
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=path.parent, prefix=f".{path.stem}-") as tmp:
        src, lib = Path(tmp) / "fixed_order_gemm.c", Path(tmp) / path.name
        src.write_text(SOURCE)
        proc = subprocess.run([cc, *CFLAGS, "-o", str(lib), str(src), "-lm"], capture_output=True, text=True)
        if proc.returncode:
            raise TactilepipeError(f"compiling the fixed-order kernels with {cc} failed: {proc.stderr.strip()[:500]}")
        os.replace(lib, path)          # atomic: a concurrent job sees no library or the whole of it
    return path


def _library():
    global _lib
    if _lib is None:
        lib = ctypes.CDLL(str(build_library()))
        L, P = ctypes.c_long, ctypes.c_void_p
        for name in ("fo_gemm", "fo_gemm_reference"):
            getattr(lib, name).argtypes = [L, L, L, P, L, L, P, L, L, P, L, L]
        lib.fo_gemm.restype = ctypes.c_int
        lib.fo_im2col.argtypes = [L, L, L, L, P, L, L, L, L] + [L] * 8 + [P]
        lib.fo_col2im.argtypes = [L, L, L, L, P] + [L] * 8 + [P]
        lib.fo_colsum.argtypes = [L, L, P, L, L, P]
        for name in ("fo_gemm_reference", "fo_im2col", "fo_col2im", "fo_colsum"):
            getattr(lib, name).restype = None
        _lib = lib
    return _lib


def gemm(a: torch.Tensor, b: torch.Tensor, reference: bool = False, out: torch.Tensor | None = None) -> torch.Tensor:
    """a @ b for 2-D float32 CPU tensors of any strides, each element one FMA chain over k in
    order, into ``out`` if given (any strides). ``reference``: the same chains computed one element
    at a time (for tests)."""
    if a.dtype != torch.float32 or b.dtype != torch.float32 or a.device.type != "cpu" or b.device.type != "cpu":
        raise TactilepipeError(f"fixed-order gemm takes float32 CPU tensors, got {a.dtype} on {a.device} and "
                               f"{b.dtype} on {b.device}")
    (m, k), (k2, n) = a.shape, b.shape
    if k != k2:
        raise TactilepipeError(f"fixed-order gemm: inner sizes differ ({tuple(a.shape)} @ {tuple(b.shape)})")
    if out is None:
        out = torch.empty(m, n, dtype=torch.float32)
    elif tuple(out.shape) != (m, n) or out.dtype != torch.float32:
        raise TactilepipeError(f"fixed-order gemm: out is {tuple(out.shape)} {out.dtype}, not ({m}, {n}) float32")
    if m and n:
        lib = _library()
        args = (m, n, k, a.data_ptr(), a.stride(0), a.stride(1), b.data_ptr(), b.stride(0), b.stride(1),
                out.data_ptr(), out.stride(0), out.stride(1))
        if reference:
            lib.fo_gemm_reference(*args)
        elif lib.fo_gemm(*args):
            raise MemoryError("fixed-order gemm: no memory for its packing buffers")
    return out


def _bias_grad(g: torch.Tensor) -> torch.Tensor:
    """Column sums of the (rows, n) gradient, each one chain over the rows in order: the product
    with a row of ones, as plain additions (fma(1, x, acc) is acc + x)."""
    rows, n = g.shape
    out = torch.empty(n, dtype=torch.float32)
    _library().fo_colsum(rows, n, g.data_ptr(), g.stride(0), g.stride(1), out.data_ptr())
    return out


def _out_size(size: int, kernel: int, stride: int, padding: int) -> int:
    return (size + 2 * padding - kernel) // stride + 1


def _columns(x: torch.Tensor, kh: int, kw: int, stride: tuple, padding: tuple) -> tuple[torch.Tensor, int, int]:
    """im2col of an NHWC tensor (any strides): (B*Ho*Wo, kh*kw*C), taps outer, channels inner."""
    b, h, w, c = x.shape
    (sh, sw), (ph, pw) = stride, padding
    ho, wo = _out_size(h, kh, sh, ph), _out_size(w, kw, sw, pw)
    if kh == kw == 1 and ph == pw == 0 and sh == sw == 1 and x.is_contiguous():
        return x.view(b * h * w, c), ho, wo
    cols = torch.empty(b * ho * wo, kh * kw * c, dtype=torch.float32)
    _library().fo_im2col(b, h, w, c, x.data_ptr(), *x.stride(), kh, kw, sh, sw, ph, pw, ho, wo, cols.data_ptr())
    return cols, ho, wo


def _uncolumns(gc: torch.Tensor, shape: tuple, kh: int, kw: int, stride: tuple, padding: tuple) -> torch.Tensor:
    """col2im: the NHWC input's gradient from its columns' gradient ``gc`` (contiguous), each element
    the sum of the taps that read it, from 0 in increasing tap order (fixed_order_c.py fo_col2im)."""
    b, h, w, c = shape
    (sh, sw), (ph, pw) = stride, padding
    gx = torch.empty(b, h, w, c, dtype=torch.float32)
    _library().fo_col2im(b, h, w, c, gc.data_ptr(), kh, kw, sh, sw, ph, pw, _out_size(h, kh, sh, ph),
                         _out_size(w, kw, sw, pw), gx.data_ptr())
    return gx


class _Conv2d(torch.autograd.Function):
    @staticmethod
    def forward(ctx, x, weight, bias, stride, padding):
        n, c, kh, kw = weight.shape
        xh = x.permute(0, 2, 3, 1)                           # NHWC (a view for a channels-last x)
        cols, ho, wo = _columns(xh, kh, kw, stride, padding)
        wm = weight.permute(0, 2, 3, 1).reshape(n, kh * kw * c)    # (N, K), K in the columns' order
        # the output is the tensor returned (not a view of one made here: autograd refuses in-place
        # ops on a custom function's views, and ReLU(inplace) follows)
        y = torch.empty(x.shape[0], n, ho, wo, memory_format=torch.channels_last)
        yh = y.permute(0, 2, 3, 1)
        gemm(cols, wm.t(), out=yh.view(-1, n))
        if bias is not None:
            yh += bias
        ctx.save_for_backward(cols, wm)
        ctx.geometry = (tuple(x.shape), kh, kw, stride, padding, bias is not None)
        return y

    @staticmethod
    def backward(ctx, gy):
        cols, wm = ctx.saved_tensors
        (b, c, h, w), kh, kw, (sh, sw), (ph, pw), has_bias = ctx.geometry
        n = wm.shape[0]
        g = gy.permute(0, 2, 3, 1).reshape(-1, n)            # (B*Ho*Wo, N)
        gx = gw = gb = None
        if ctx.needs_input_grad[1]:
            gw = gemm(g.t(), cols).view(n, kh, kw, c).permute(0, 3, 1, 2)
        if has_bias and ctx.needs_input_grad[2]:
            gb = _bias_grad(g)
        if ctx.needs_input_grad[0]:
            gc = gemm(g, wm)                                  # (B*Ho*Wo, kh*kw*C)
            if kh == kw == 1 and ph == pw == 0 and sh == sw == 1:
                gxh = gc.view(b, h, w, c)
            else:
                gxh = _uncolumns(gc, (b, h, w, c), kh, kw, (sh, sw), (ph, pw))
            gx = gxh.permute(0, 3, 1, 2)
        return gx, gw, gb, None, None


class _Linear(torch.autograd.Function):
    @staticmethod
    def forward(ctx, x, weight, bias):
        x2 = x.reshape(-1, x.shape[-1])
        y = torch.empty(*x.shape[:-1], weight.shape[0])
        gemm(x2, weight.t(), out=y.view(-1, weight.shape[0]))
        if bias is not None:
            y += bias
        ctx.save_for_backward(x2, weight)
        ctx.shape, ctx.has_bias = x.shape, bias is not None
        return y

    @staticmethod
    def backward(ctx, gy):
        x2, weight = ctx.saved_tensors
        g = gy.reshape(-1, weight.shape[0])
        gx = gemm(g, weight).view(ctx.shape) if ctx.needs_input_grad[0] else None
        gw = gemm(g.t(), x2) if ctx.needs_input_grad[1] else None
        gb = _bias_grad(g) if ctx.has_bias and ctx.needs_input_grad[2] else None
        return gx, gw, gb


def conv2d(x, weight, bias, stride, padding, groups: int = 1):
    """F.conv2d (zero padding, dilation 1), through the fixed-order kernels while enabled."""
    if not _enabled or groups != 1 or x.dtype != torch.float32 or x.device.type != "cpu":
        return F.conv2d(x, weight, bias, stride, padding, 1, groups)
    return _Conv2d.apply(x, weight, bias, tuple(stride), tuple(padding))


def linear(x, weight, bias):
    """F.linear, through the fixed-order kernels while enabled."""
    if not _enabled or x.dtype != torch.float32 or x.device.type != "cpu":
        return F.linear(x, weight, bias)
    return _Linear.apply(x, weight, bias)
