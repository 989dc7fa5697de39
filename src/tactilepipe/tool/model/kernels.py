"""Which numerical kernels the tool models train and predict with: ``portable`` or ``native``.

``native`` lets every library pick its fastest code for this CPU: oneDNN's JIT convolutions,
MKL's own dispatch, ATen's widest vector build, and as many threads as asked for. The bytes of
a trained model then depend on the CPU's vendor, vector width, cache sizes and the thread count.

``portable`` pins every numerical path to code whose results do not depend on them
(docs/reproducibility.md, "Portable kernels", says why; benchmarks/record.md has the measurements):

- oneDNN off: its JIT kernels block by the CPU's cache sizes and ISA; convolutions run as ATen's
  im2col + matrix multiply instead. NNPACK off too (its own CPU dispatch).
- MKL's conditional numerical reproducibility, branch COMPATIBLE. On AMD processors MKL takes every
  other branch (AVX2, AVX512, ...) as AUTO, its own dispatch, so only COMPATIBLE names the same
  code on Intel and AMD.
- ATen's CPU kernels at AVX2: the same machine code on every x86 CPU that has AVX2 (all the
  project has met); wider builds sum in another order. A CPU without AVX2 is refused.
- One intra-op thread: ATen's parallel reductions and the convolution's weight gradient split
  their sums by thread.
- The network's convolutions and linear layers on the fixed-order kernels (fixed_order.py): each
  output element one FMA chain in a fixed order, the same bits on every CPU with AVX2 and FMA, at
  AVX2 speed instead of MKL COMPATIBLE's SSE2.

The MKL and ATen choices are read from the environment when torch loads, so ``use_kernels``
must run before the first ``import torch`` of the process: a stage calls it first thing.
"""

from __future__ import annotations

import os
import sys

from tactilepipe.core.allocator import keep_freed_memory
from tactilepipe.core.errors import ConfigError, TactilepipeError

KERNEL_MODES = ("portable", "native")
PORTABLE_ENV = {
    "ATEN_CPU_CAPABILITY": "avx2",
    "MKL_CBWR": "COMPATIBLE",
    "MKL_DYNAMIC": "FALSE",
    "OMP_DYNAMIC": "FALSE",
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}
PORTABLE_CAPABILITY = "AVX2"
_MKL_CBWR_BRANCH = 1          # mkl_cbwr_get's query for the code branch
_MKL_BRANCH_NAMES = {1: "OFF", 2: "AUTO", 3: "COMPATIBLE"}


def check_mode(mode: str) -> None:
    if mode not in KERNEL_MODES:
        raise ConfigError(f"unknown tool_train.kernels '{mode}' (one of {', '.join(KERNEL_MODES)})")


def use_kernels(mode: str) -> dict:
    """Select ``mode``'s kernels for this process and return ``active_kernels()``. For
    ``portable`` this must come before torch is first imported (the environment it sets is read
    then); called later it raises unless the process was already started that way."""
    check_mode(mode)
    keep_freed_memory()                      # speed only: where memory comes from, not what is computed
    if mode == "portable":
        unset = {k: v for k, v in PORTABLE_ENV.items() if os.environ.get(k) != v}
        if unset and "torch" in sys.modules:
            raise TactilepipeError(
                "portable kernels must be chosen before torch is loaded, and this process loaded it with "
                + ", ".join(f"{k}={os.environ.get(k)!r}" for k in unset)
                + ": run the stage in its own process (tactilepipe tool-train does)")
        os.environ.update(PORTABLE_ENV)
    import torch

    from tactilepipe.tool.model import fixed_order
    if mode == "portable":
        torch.backends.mkldnn.enabled = False
        torch.backends.nnpack.set_flags(False)
        torch.set_num_threads(1)
    else:
        torch.backends.mkldnn.enabled = True
        torch.backends.nnpack.set_flags(True)
    fixed_order.set_enabled(mode == "portable")
    return require_active(mode)


def active_kernels() -> dict:
    """The kernel settings in force in this process (recorded with every trained model)."""
    import torch

    from tactilepipe.tool.model import fixed_order
    return {"aten_capability": torch.backends.cpu.get_cpu_capability(),
            "mkl_cbwr": _mkl_branch(),
            "onednn": bool(torch.backends.mkldnn.enabled),
            "nnpack": bool(torch._C._get_nnpack_enabled()),     # torch.backends.nnpack has a setter only
            "threads": torch.get_num_threads(),
            "layers": "fixed-order" if fixed_order.enabled() else "torch"}


def require_active(mode: str) -> dict:
    """``active_kernels()`` plus the mode, after checking that ``mode``'s pins are in force: a
    portable run on settings that are not portable would record bytes no other machine can
    reproduce, so it stops instead, saying which pin is missing."""
    check_mode(mode)
    active = active_kernels()
    if mode == "portable":
        wrong = []
        if active["aten_capability"] != PORTABLE_CAPABILITY:
            wrong.append(f"torch dispatches {active['aten_capability']}, not {PORTABLE_CAPABILITY} "
                         f"(a CPU without AVX2, or torch loaded before the kernels were chosen)")
        if active["mkl_cbwr"] != "COMPATIBLE":
            wrong.append(f"MKL's reproducible branch is {active['mkl_cbwr']}, not COMPATIBLE")
        if active["onednn"] or active["nnpack"]:
            wrong.append("oneDNN or NNPACK is on")
        if active["threads"] != 1:
            wrong.append(f"{active['threads']} intra-op threads, not 1")
        if active["layers"] != "fixed-order":
            wrong.append("the convolutions and linear layers run torch's kernels, not the fixed-order ones")
        if wrong:
            raise TactilepipeError("portable kernels are not in force: " + "; ".join(wrong)
                                   + " (tool_train.kernels: native runs without these pins)")
    return {"mode": mode, **active}


def _mkl_branch() -> str | None:
    """MKL's active code branch, read from the MKL that torch links (None: not found there)."""
    import ctypes

    import torch
    lib_dir = os.path.join(os.path.dirname(torch.__file__), "lib")
    try:
        get = ctypes.CDLL(os.path.join(lib_dir, "libtorch_cpu.so")).mkl_serv_cbwr_get
    except (OSError, AttributeError):
        return None
    get.restype, get.argtypes = ctypes.c_int, [ctypes.c_int]
    branch = get(_MKL_CBWR_BRANCH)
    return _MKL_BRANCH_NAMES.get(branch, f"code {branch}")
