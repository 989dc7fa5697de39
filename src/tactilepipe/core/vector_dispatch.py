"""The vector code NumPy, OpenCV and OpenBLAS run: what every x86-64 CPU with AVX2 and FMA runs.

Each of these libraries carries several builds of its hot loops and picks one by the CPU it
finds: AVX2, or AVX-512 where the CPU has it. The builds sum in other orders and NumPy's AVX-512
transcendental functions are other approximations, so the same recording gave other bytes on an
AVX-512 machine than on an AVX2 one. Measured on the smoke build: the simulated ``tool_shear``
frames differed (its trials are rendered through OpenCV's ``remap``), and OpenCV's ``remap``,
``GaussianBlur`` and ``Sobel`` on float32 images give other bytes here with their AVX2 code
switched off than with it (benchmarks/record.md, "Portability record and vector caps"). ``pin`` caps each library at AVX2 before it
loads. On the AVX2 machine that made the committed results it changes no library's choice (NumPy
ran its AVX2 code, OpenBLAS its Haswell kernels), so those results stand.

The choice is read from the environment when each library loads, so the command line calls
``pin`` first thing, before anything imports NumPy or OpenCV. A value the user set is kept.
"""

from __future__ import annotations

import os
import sys

from tactilepipe.core.environment import cpu_flags

# NumPy 2's dispatch targets above AVX2 (x86-64-v3); OpenBLAS's AVX2 kernel set (the one it picks
# itself on AVX2 CPUs, Intel or AMD)
NUMPY_ABOVE_AVX2 = "X86_V4 AVX512_ICL AVX512_SPR"
OPENBLAS_AVX2 = "Haswell"
# OpenCV's names of the AVX-512 feature groups it dispatches on, each with the /proc/cpuinfo flags
# the group needs. OpenCV prints a warning for every name the CPU lacks, at every import (the
# Xeon Phi groups KNL and KNM on every other CPU), so only the groups the CPU has are named.
_AVX512_COMMON = {"avx512f", "avx512cd"}
_AVX512_SKX = _AVX512_COMMON | {"avx512bw", "avx512dq", "avx512vl"}
_AVX512_KNL = _AVX512_COMMON | {"avx512er", "avx512pf"}
OPENCV_AVX512 = {
    "AVX512F": {"avx512f"},
    "AVX512-COMMON": _AVX512_COMMON,
    "AVX512-SKX": _AVX512_SKX,
    "AVX512-CLX": _AVX512_SKX | {"avx512_vnni"},
    "AVX512-CNL": _AVX512_SKX | {"avx512ifma", "avx512vbmi"},
    "AVX512-ICL": _AVX512_SKX | {"avx512ifma", "avx512vbmi", "avx512_vnni", "avx512_vbmi2", "avx512_bitalg",
                                 "avx512_vpopcntdq"},
    "AVX512-KNL": _AVX512_KNL,
    "AVX512-KNM": _AVX512_KNL | {"avx512_4fmaps", "avx512_4vnniw", "avx512_vpopcntdq"},
}
VARIABLES = ("NPY_DISABLE_CPU_FEATURES", "OPENCV_CPU_DISABLE", "OPENBLAS_CORETYPE")
LIBRARIES = ("numpy", "cv2")


def pinned_environment(flags: set[str]) -> dict[str, str]:
    """The variables that cap each library at AVX2 on a CPU with ``flags`` (/proc/cpuinfo's names).
    None without AVX2 and FMA: the libraries then run older code than other machines, and nothing
    here can give them the AVX2 results. OpenCV's cap names the AVX-512 groups the CPU has, and
    is left out where it has none."""
    if not {"avx2", "fma"} <= flags:
        return {}
    env = {"NPY_DISABLE_CPU_FEATURES": NUMPY_ABOVE_AVX2, "OPENBLAS_CORETYPE": OPENBLAS_AVX2}
    opencv = [name for name, needs in OPENCV_AVX512.items() if needs <= flags]
    if opencv:
        env["OPENCV_CPU_DISABLE"] = ",".join(opencv)
    return env


def pin() -> dict[str, str]:
    """Set the caps for this process (and the processes it starts) unless the user set them, and
    return what is in force. Called once NumPy or OpenCV is loaded it can no longer set a cap: it
    then raises unless every cap is already in force (the process was pinned before), since
    going on would compute other bytes than every stage, silently."""
    wanted = pinned_environment(cpu_flags())
    loaded = [name for name in LIBRARIES if name in sys.modules]
    if loaded:
        uncapped = _uncapped(loaded, wanted)
        if uncapped:
            raise RuntimeError(
                f"vector_dispatch.pin() called after {' and '.join(loaded)} loaded: {', '.join(uncapped)} already "
                f"run(s) code above AVX2 here, which gives other bytes than the stages. Call it before anything "
                f"imports NumPy or OpenCV (the command line does so first), or set {', '.join(wanted)} in the "
                f"environment before the process starts")
    else:
        for key, value in wanted.items():
            os.environ.setdefault(key, value)
    return {k: os.environ[k] for k in VARIABLES if k in os.environ}


# OpenCV's id of its AVX-512 base feature (cv::CPU_AVX_512F): reported off once capped
_OPENCV_AVX512F = 13


def _uncapped(loaded: list[str], wanted: dict[str, str]) -> list[str]:
    """The loaded libraries that run code above a cap this CPU needs, by their own feature tables
    (the variable was missing, or set after the library read it). A value the user set is theirs."""
    def ours(key: str) -> bool:
        return key in wanted and os.environ.get(key, wanted[key]) == wanted[key]
    out = []
    if "numpy" in loaded and ours("NPY_DISABLE_CPU_FEATURES"):
        from numpy._core._multiarray_umath import __cpu_features__ as features
        if any(features.get(name) for name in NUMPY_ABOVE_AVX2.split()):
            out.append("NumPy")
    if "cv2" in loaded and ours("OPENCV_CPU_DISABLE") and sys.modules["cv2"].checkHardwareSupport(_OPENCV_AVX512F):
        out.append("OpenCV")
    return out
