"""The machine, packages and commit a result is made with: what a scene's provenance.json records
and what the portability record tells machine kinds apart by."""

from __future__ import annotations

import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path

PACKAGES = ("torch", "numpy", "scikit-learn", "pandas", "snakemake", "dvc", "dvc-data")
# environment variables that choose the code of torch's, oneDNN's, MKL's, NumPy's, OpenCV's and
# OpenBLAS's kernels (the last three: core/vector_dispatch.py)
KERNEL_VARIABLES = ("ATEN_CPU_CAPABILITY", "ONEDNN_MAX_CPU_ISA", "DNNL_MAX_CPU_ISA", "MKL_CBWR",
                    "MKL_ENABLE_INSTRUCTIONS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NPY_DISABLE_CPU_FEATURES",
                    "OPENCV_CPU_DISABLE", "OPENBLAS_CORETYPE")


def environment() -> dict:
    """Package versions, the CPU and its vector extensions, and the settings that choose the
    numerical kernels (the same code and data give slightly different trained models on different
    instruction sets). Without importing torch (seconds per process): the kernels a model trained
    with are in its run's eval.json; ``torch_cpu_capability`` gives torch's choice here."""
    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    env = {"python": platform.python_version(), "packages": versions, "machine": platform.machine(),
           "cpu": _cpu(), "kernel_settings": {k: os.environ.get(k) for k in KERNEL_VARIABLES}}
    return env


def torch_cpu_capability() -> str | None:
    """The vector code torch's kernels chose on this machine (imports torch)."""
    try:
        import torch
    except ImportError:
        return None
    return torch.backends.cpu.get_cpu_capability()


def _cpuinfo() -> tuple[dict[str, str], set[str]]:
    """The first CPU's fields of /proc/cpuinfo and its flags (both empty where there is none)."""
    flags, fields = set(), {}
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            key, value = key.strip(), value.strip()
            if key == "flags":
                flags = set(value.split())
            elif key not in fields:
                fields[key] = value
    except OSError:
        pass
    return fields, flags


def cpu_flags() -> set[str]:
    """The CPU's feature flags under /proc/cpuinfo's names (avx2, fma, avx512f, ...; Linux)."""
    return _cpuinfo()[1]


def _cpu() -> dict:
    """CPU vendor, model (name, family and number: a model name such as "AMD EPYC" covers several
    generations) and the vector extensions the math libraries choose kernels by (Linux)."""
    fields, flags = _cpuinfo()
    model = fields.get("model name") or platform.processor() or None
    return {"model": model, "vendor": fields.get("vendor_id"), "family": fields.get("cpu family"),
            "model_number": fields.get("model"),
            "vector_extensions": sorted(f for f in flags if f.startswith(("avx", "amx", "fma")))}


def git_state(root: str | Path = ".") -> dict:
    """The commit the code was at, and whether the workflow's code or parameters had uncommitted
    changes when the result was made (then the commit alone does not describe it)."""
    def git(*args):
        proc = subprocess.run(["git", *args], cwd=root, capture_output=True, text=True)
        return proc.stdout.strip() if proc.returncode == 0 else None
    try:
        commit = git("rev-parse", "HEAD")
        dirty = git("status", "--porcelain", "--", "src", "workflow", "Snakefile", "params.yaml")
    except OSError:
        commit = dirty = None
    return {"commit": commit, "uncommitted_changes": bool(dirty) if commit else None}
