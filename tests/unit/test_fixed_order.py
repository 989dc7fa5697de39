"""The fixed-order kernels (tool/model/fixed_order.py): the blocked product is the element-by-element
FMA chain bit for bit, the layers compute what torch's do, and the bytes are the same on other CPU
models (emulated by QEMU user mode, where installed)."""

from __future__ import annotations

import hashlib
import shutil
import subprocess
from concurrent.futures import ThreadPoolExecutor

import pytest
import torch
from torch.nn import functional as F

from tactilepipe.tool.model import fixed_order

# Shapes that cross the register tile (6 x 16), the row block (96) and the K block (256), and none.
SHAPES = [(1, 1, 1), (6, 16, 256), (7, 17, 257), (97, 33, 600), (5, 3, 0), (150, 40, 18)]
EMULATED = ("Haswell-v4", "EPYC-Rome")          # Intel AVX2, AMD AVX2 (the host may have AVX-512)

# Calls the library the network uses, on inputs from a fixed integer generator, and writes the
# products' bytes: the same program under each CPU model.
PROBE = r"""
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
typedef int (*gemm_t)(long, long, long, const float *, long, long, const float *, long, long, float *, long, long);
static unsigned long long s = 88172645463325252ULL;
static float draw(void) { s ^= s << 13; s ^= s >> 7; s ^= s << 17; return (float)((long)(s % 2000001) - 1000000) / 7e5f; }
int main(int argc, char **argv) {
    void *h = dlopen(argv[1], RTLD_NOW);
    gemm_t gemm = h ? (gemm_t)dlsym(h, "fo_gemm") : 0;
    long shapes[][3] = {{97, 33, 600}, {40, 130, 257}, {300, 64, 18}, {6, 512, 1030}};
    if (!gemm) return 2;
    for (int t = 0; t < 4; t++) {
        long m = shapes[t][0], n = shapes[t][1], k = shapes[t][2];
        float *a = malloc(sizeof(float) * m * k), *b = malloc(sizeof(float) * k * n), *c = malloc(sizeof(float) * m * n);
        for (long i = 0; i < m * k; i++) a[i] = draw();
        for (long i = 0; i < k * n; i++) b[i] = draw();
        if (gemm(m, n, k, a, k, 1, b, 1, k, c, n, 1)) return 3;     /* B read transposed, as a weight */
        fwrite(c, sizeof(float), m * n, stdout);
        free(a); free(b); free(c);
    }
    return 0;
}
"""


@pytest.fixture(scope="module", autouse=True)
def kernel_cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TACTILEPIPE_KERNEL_CACHE", str(tmp_path_factory.mktemp("kernel-cache")))
        yield fixed_order.build_library()


@pytest.mark.parametrize("m,n,k", SHAPES)
def test_the_blocked_product_is_the_fma_chain_bit_for_bit(m, n, k):
    g = torch.Generator().manual_seed(m * 1000 + n + k)
    a, b = torch.randn(m, k, generator=g), torch.randn(k, n, generator=g)
    chain = fixed_order.gemm(a, b, reference=True)
    assert torch.equal(fixed_order.gemm(a, b), chain)
    # another memory layout of the same operands, and a strided output: the same chains
    out = torch.empty(n, m).t()
    fixed_order.gemm(a.t().contiguous().t(), b.t().contiguous().t(), out=out)
    assert torch.equal(out, chain)
    torch.testing.assert_close(chain, a @ b, rtol=1e-4, atol=1e-4 * max(k, 1) ** 0.5)


@pytest.mark.parametrize("b,c,h,n,k,s,p,bias", [(4, 3, 9, 5, 3, 1, 1, True), (4, 8, 7, 16, 3, 2, 1, False),
                                                (2, 8, 5, 7, 1, 2, 0, False), (3, 6, 4, 20, 1, 1, 0, True)])
def test_the_convolution_and_its_gradients_are_torchs(b, c, h, n, k, s, p, bias):
    g = torch.Generator().manual_seed(b * c * h)
    cl = torch.channels_last
    x = torch.randn(b, c, h, h, generator=g).contiguous(memory_format=cl).requires_grad_()
    w = torch.randn(n, c, k, k, generator=g).contiguous(memory_format=cl).requires_grad_()
    bv = torch.randn(n, generator=g).requires_grad_() if bias else None
    inputs = [x, w] + ([bv] if bias else [])
    y = fixed_order._Conv2d.apply(x, w, bv, (s, s), (p, p))
    want = F.conv2d(x, w, bv, s, p)
    gy = torch.randn(want.shape, generator=g)
    torch.testing.assert_close(y, want, rtol=1e-4, atol=1e-4)
    for got, ref in zip(torch.autograd.grad(y, inputs, gy), torch.autograd.grad(want, inputs, gy)):
        torch.testing.assert_close(got, ref, rtol=1e-4, atol=1e-4)


def _reference_conv(x, w, bias, gy, stride, padding):
    """The convolution's forward and gradients spelled out with torch's own ops: im2col as a strided
    copy, col2im as one strided addition per tap into zeros (taps in increasing order), the bias'
    gradient as the product with a row of ones. The C loops must give these bytes."""
    (sh, sw), (ph, pw) = stride, padding
    n, c, kh, kw = w.shape
    xh = F.pad(x.permute(0, 2, 3, 1), (0, 0, pw, pw, ph, ph))
    b, hp, wp, _ = xh.shape
    ho, wo = (hp - kh) // sh + 1, (wp - kw) // sw + 1
    s0, s1, s2, s3 = xh.stride()
    cols = xh.as_strided((b, ho, wo, kh, kw, c), (s0, s1 * sh, s2 * sw, s1, s2, s3)).reshape(b * ho * wo, -1)
    wm = w.permute(0, 2, 3, 1).reshape(n, -1)
    y = fixed_order.gemm(cols, wm.t()).view(b, ho, wo, n)
    g = gy.permute(0, 2, 3, 1).reshape(-1, n)
    gw = fixed_order.gemm(g.t(), cols).view(n, kh, kw, c).permute(0, 3, 1, 2)
    g6 = fixed_order.gemm(g, wm).view(b, ho, wo, kh, kw, c)
    gxp = torch.zeros(b, hp, wp, c)
    for i in range(kh):
        for j in range(kw):
            gxp[:, i:i + sh * (ho - 1) + 1:sh, j:j + sw * (wo - 1) + 1:sw, :] += g6[:, :, :, i, j, :]
    gx = gxp[:, ph:hp - ph, pw:wp - pw, :].permute(0, 3, 1, 2)
    gb = fixed_order.gemm(torch.ones(1, g.shape[0]), g)[0] if bias is not None else None
    return (y + (bias if bias is not None else 0)).permute(0, 3, 1, 2), gx, gw, gb


@pytest.mark.parametrize("b,c,h,n,k,s,p", [(4, 3, 9, 5, 3, 1, 1), (4, 8, 7, 16, 3, 2, 1), (2, 8, 5, 7, 1, 2, 0),
                                           (3, 6, 9, 20, 7, 2, 3), (2, 5, 2, 6, 7, 1, 3), (5, 70, 4, 9, 3, 1, 1)])
def test_the_convolutions_c_loops_give_the_bytes_of_torchs_copies_and_additions(b, c, h, n, k, s, p):
    g = torch.Generator().manual_seed(b * c * h + k)
    cl = torch.channels_last
    x = torch.randn(b, c, h, h, generator=g).contiguous(memory_format=cl).requires_grad_()
    w = torch.randn(n, c, k, k, generator=g).contiguous(memory_format=cl).requires_grad_()
    bv = torch.randn(n, generator=g).requires_grad_()
    y = fixed_order._Conv2d.apply(x, w, bv, (s, s), (p, p))
    gy = torch.randn(y.shape, generator=g).contiguous(memory_format=cl)
    got = (y, *torch.autograd.grad(y, [x, w, bv], gy))
    with torch.no_grad():
        want = _reference_conv(x, w, bv, gy, (s, s), (p, p))
    for name, a, r in zip(("output", "input grad", "weight grad", "bias grad"), got, want):
        assert torch.equal(a, r), name


def test_the_linear_layer_and_its_gradients_are_torchs():
    g = torch.Generator().manual_seed(3)
    x, w, bv = (torch.randn(*shape, generator=g).requires_grad_() for shape in [(3, 5, 7), (9, 7), (9,)])
    y = fixed_order._Linear.apply(x, w, bv)
    want = F.linear(x, w, bv)
    gy = torch.randn(want.shape, generator=g)
    torch.testing.assert_close(y, want, rtol=1e-5, atol=1e-5)
    for got, ref in zip(torch.autograd.grad(y, [x, w, bv], gy), torch.autograd.grad(want, [x, w, bv], gy)):
        torch.testing.assert_close(got, ref, rtol=1e-5, atol=1e-5)


def test_the_layers_take_torchs_path_unless_enabled(monkeypatch):
    calls = []
    monkeypatch.setattr(fixed_order, "gemm", lambda *a, **k: calls.append(1) or torch.zeros(0))
    x, w = torch.randn(2, 3), torch.randn(4, 3)
    fixed_order.set_enabled(False)
    fixed_order.linear(x, w, None)
    assert calls == []


@pytest.mark.skipif(shutil.which("qemu-x86_64") is None, reason="QEMU user mode (Debian's qemu-user) not installed")
def test_the_bytes_are_the_same_on_emulated_cpus(kernel_cache, tmp_path):
    src, exe = tmp_path / "probe.c", tmp_path / "probe"
    src.write_text(PROBE)
    subprocess.run(["gcc", "-O2", "-o", str(exe), str(src), "-ldl"], check=True)

    def run(cpu):
        cmd = [str(exe), str(kernel_cache)] if cpu is None else ["qemu-x86_64", "-cpu", cpu, str(exe), str(kernel_cache)]
        proc = subprocess.run(cmd, capture_output=True, check=True)
        assert len(proc.stdout) == 4 * (97 * 33 + 40 * 130 + 300 * 64 + 6 * 512)
        return hashlib.sha256(proc.stdout).hexdigest()

    with ThreadPoolExecutor(3) as pool:
        digests = dict(zip(("host",) + EMULATED, pool.map(run, (None,) + EMULATED)))
    assert len(set(digests.values())) == 1, digests


TRAIN_TWICE = r"""
import json, sys
from pathlib import Path
from tactilepipe.tool.model.kernels import use_kernels
active = use_kernels("portable")                # before torch loads, as the training stage does
sys.path.insert(0, sys.argv[2])
from support.tool_data import make_dataset, make_split_dict, quick_cfg
from tactilepipe.tool.data.loader import ToolFrames
from tactilepipe.tool.model.train import train
from tactilepipe.tool.report.portability import weights_digest
root = Path(sys.argv[1])
data = ToolFrames(make_dataset(root / "data", n_trials=8, per_trial=4), "normal")
digests = []
for run in ("a", "b"):
    cfg = quick_cfg(kernels="portable", num_threads=1, max_epochs=1, width=8, bn_recalibration_batches=0)
    train(data, make_split_dict(data), cfg, root / run, progress=False)
    digests.append(weights_digest(root / run / "best.pt"))
print(json.dumps({"active": active, "digests": digests}))
"""


@pytest.mark.slow
def test_portable_training_runs_on_the_fixed_order_kernels_and_repeats_its_bytes(tmp_path):
    import json
    import sys
    from pathlib import Path
    proc = subprocess.run([sys.executable, "-c", TRAIN_TWICE, str(tmp_path), str(Path(__file__).parents[1])],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["active"]["layers"] == "fixed-order"
    a, b = out["digests"]
    assert a == b
