"""The kernel modes: a portable run refuses to start on settings that are not portable, instead of
recording bytes no other machine can reproduce (the bytes themselves: tests/integration/test_portability.py)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from tactilepipe.core.errors import ConfigError, TactilepipeError
from tactilepipe.tool.model import kernels


def test_an_unknown_mode_is_refused():
    with pytest.raises(ConfigError, match="unknown tool_train.kernels 'fast'"):
        kernels.check_mode("fast")


def test_portable_cannot_be_chosen_after_torch_loaded_without_it(monkeypatch):
    import torch  # noqa: F401  (this process has torch, loaded without the portable pins)
    monkeypatch.delenv("MKL_CBWR", raising=False)
    with pytest.raises(TactilepipeError, match="before torch is loaded.*MKL_CBWR=None"):
        kernels.use_kernels("portable")


def test_a_process_without_the_pins_is_not_portable():
    with pytest.raises(TactilepipeError, match="portable kernels are not in force: .*MKL's reproducible branch is"):
        kernels.require_active("portable")
    assert kernels.require_active("native")["mode"] == "native"


def test_a_fresh_process_gets_every_pin():
    code = ("from tactilepipe.tool.model.kernels import use_kernels; import json; "
            "print(json.dumps(use_kernels('portable')))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert proc.stdout.strip() == ('{"mode": "portable", "aten_capability": "AVX2", "mkl_cbwr": "COMPATIBLE", '
                                   '"onednn": false, "nnpack": false, "threads": 1, "layers": "fixed-order"}')


def test_training_refuses_portable_kernels_on_two_threads(tmp_path):
    from support.tool_data import make_dataset, make_split_dict, quick_cfg
    from tactilepipe.tool.data.loader import ToolFrames
    from tactilepipe.tool.model.train import train
    data = ToolFrames(make_dataset(tmp_path / "data", n_trials=8, per_trial=4), "normal")
    with pytest.raises(ConfigError, match="num_threads 2 with kernels: portable"):
        train(data, make_split_dict(data), quick_cfg(kernels="portable", num_threads=2), tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_freed_training_memory_stays_in_the_process():
    # glibc's default gives blocks of 128 KiB and more back to the kernel when freed; a training
    # step would fault them in again every time (core/allocator.py). A step's pattern: many blocks
    # allocated, written, and freed together; with the call, the next step reuses their pages.
    code = ("import ctypes, resource\n"
            "from tactilepipe.core.allocator import keep_freed_memory\n"
            "assert keep_freed_memory()\n"
            "libc = ctypes.CDLL(None); libc.malloc.restype = ctypes.c_void_p; libc.malloc.argtypes = [ctypes.c_size_t]\n"
            "libc.free.argtypes = [ctypes.c_void_p]\n"
            "def touch():\n"
            "    blocks = [libc.malloc(1 << 20) for _ in range(16)]\n"
            "    for p in blocks: ctypes.memset(p, 1, 1 << 20)\n"
            "    for p in blocks: libc.free(p)\n"
            "touch(); before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt\n"
            "for _ in range(5): touch()\n"
            "print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)\n")
    faults = int(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout)
    assert faults < 100                  # 5 x 16 x 256 pages if the blocks went back to the kernel
    without = code.replace("assert keep_freed_memory()", "pass")
    assert int(subprocess.run([sys.executable, "-c", without], capture_output=True, text=True,
                              check=True).stdout) > 5 * 1000
