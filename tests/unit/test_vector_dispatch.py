"""NumPy, OpenCV and OpenBLAS capped at AVX2 in every stage process (core/vector_dispatch.py): the
command line sets the caps before either library loads, and each library honours them."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from tactilepipe.core import vector_dispatch
from tactilepipe.core.environment import cpu_flags

AVX2 = {"sse4_2", "avx", "avx2", "fma"}


SKYLAKE_X = AVX2 | {"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"}
ZEN_4 = SKYLAKE_X | {"avx512ifma", "avx512vbmi", "avx512_vnni", "avx512_vbmi2", "avx512_bitalg", "avx512_vpopcntdq",
                     "avx512_bf16"}
KNIGHTS_LANDING = AVX2 | {"avx512f", "avx512cd", "avx512er", "avx512pf"}
CPUS = {  # /proc/cpuinfo's AVX-512 flags of each generation -> the OpenCV groups it has
    "skylake_x": (SKYLAKE_X, ["AVX512F", "AVX512-COMMON", "AVX512-SKX"]),
    "cascade_lake": (SKYLAKE_X | {"avx512_vnni"}, ["AVX512F", "AVX512-COMMON", "AVX512-SKX", "AVX512-CLX"]),
    "cannon_lake": (SKYLAKE_X | {"avx512ifma", "avx512vbmi"}, ["AVX512F", "AVX512-COMMON", "AVX512-SKX", "AVX512-CNL"]),
    "zen4": (ZEN_4, ["AVX512F", "AVX512-COMMON", "AVX512-SKX", "AVX512-CLX", "AVX512-CNL", "AVX512-ICL"]),
    "knights_landing": (KNIGHTS_LANDING, ["AVX512F", "AVX512-COMMON", "AVX512-KNL"]),
    "knights_mill": (KNIGHTS_LANDING | {"avx512_4fmaps", "avx512_4vnniw", "avx512_vpopcntdq"},
                     ["AVX512F", "AVX512-COMMON", "AVX512-KNL", "AVX512-KNM"]),
}


def test_the_caps_follow_the_cpu():
    avx512 = vector_dispatch.pinned_environment(SKYLAKE_X)
    assert avx512 == {"NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR", "OPENBLAS_CORETYPE": "Haswell",
                      "OPENCV_CPU_DISABLE": "AVX512F,AVX512-COMMON,AVX512-SKX"}
    # OpenCV warns at every import about a group the CPU lacks, so each CPU's cap names its own
    opencv = {name: vector_dispatch.pinned_environment(flags)["OPENCV_CPU_DISABLE"].split(",")
              for name, (flags, _) in CPUS.items()}
    assert opencv == {name: groups for name, (_, groups) in CPUS.items()}
    # on an AVX2 machine OpenCV has nothing to switch off (and would warn about each name)
    assert vector_dispatch.pinned_environment(AVX2) == {k: v for k, v in avx512.items() if k != "OPENCV_CPU_DISABLE"}
    assert vector_dispatch.pinned_environment({"sse4_2", "avx"}) == {}         # no AVX2 code to pin to


def _process(code: str, env: dict | None = None) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in vector_dispatch.VARIABLES} | (env or {})
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)


def _run(code: str, env: dict | None = None) -> list[str]:
    return _process(code, env).stdout.split()


@pytest.mark.skipif(not {"avx2", "fma"} <= cpu_flags(), reason="the caps are for CPUs with AVX2 and FMA")
def test_the_command_line_sets_the_caps_before_numpy_or_opencv_loads():
    code = ("import contextlib, io, os, sys\nfrom tactilepipe.cli.main import main\n"
            "with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):\n    main(['--help'])\n"
            "print(os.environ['OPENBLAS_CORETYPE'], 'numpy' in sys.modules or 'cv2' in sys.modules)\n"
            "import numpy, threadpoolctl\nprint([i['architecture'] for i in threadpoolctl.threadpool_info()])")
    assert _run(code) == ["Haswell", "False", "['Haswell']"]
    # a value the user set is kept
    assert _run(code, {"OPENBLAS_CORETYPE": "Sandybridge"})[:2] == ["Sandybridge", "False"]


@pytest.mark.skipif(not {"avx2", "fma"} <= cpu_flags(), reason="needs AVX2 code to switch off")
def test_numpy_and_opencv_honour_a_cap_set_this_way():
    # the same path with a cap this machine can show (its AVX2 code): each library then runs older
    # code, and OpenCV's remap gives other bytes, as it would across machines without the cap
    code = ("import hashlib\nfrom tactilepipe.core import vector_dispatch as v\n"
            "v.NUMPY_ABOVE_AVX2 = 'X86_V3 X86_V4'\nv.pinned_environment = lambda flags: {"
            "'NPY_DISABLE_CPU_FEATURES': v.NUMPY_ABOVE_AVX2, 'OPENCV_CPU_DISABLE': 'AVX2,FMA3,AVX'} if CAP else {}\n"
            "v.pin()\nimport numpy as np, cv2\nfrom numpy._core._multiarray_umath import __cpu_features__ as f\n"
            "rng = np.random.default_rng(0)\nh = rng.random((60, 80), dtype=np.float32)\n"
            "m = (np.indices((60, 80))[::-1].astype(np.float32) + rng.standard_normal((2, 60, 80)).astype(np.float32))\n"
            "out = cv2.remap(h, np.ascontiguousarray(m.transpose(1, 2, 0)), None, cv2.INTER_LINEAR)\n"
            "print(f['X86_V3'], cv2.checkHardwareSupport(11), hashlib.sha256(out.tobytes()).hexdigest()[:12])")
    capped, free = _run("CAP = True\n" + code), _run("CAP = False\n" + code)
    assert capped[:2] == ["False", "False"] and free[:2] == ["True", "True"]
    assert capped[2] != free[2]


@pytest.mark.skipif("avx512f" not in cpu_flags(), reason="only a CPU with AVX-512 has AVX-512 code to switch off")
def test_on_an_avx512_cpu_a_stage_runs_the_avx2_code():
    # OpenCV's ids: 13 AVX_512F; 256-262 the groups SKX, COMMON, KNL, KNM, CNL, CLX, ICL
    code = ("import contextlib, io\nfrom tactilepipe.cli.main import main\n"
            "with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):\n    main(['--help'])\n"
            "import numpy, cv2\nfrom numpy._core._multiarray_umath import __cpu_features__ as f\n"
            "print(f['X86_V4'], f['X86_V3'], any(cv2.checkHardwareSupport(i) for i in (13, *range(256, 263))))")
    proc = _process(code)
    assert proc.stdout.split() == ["False", "True", "False"]
    assert proc.stderr == ""             # no warning about a group this CPU lacks, in any stage's log


@pytest.mark.skipif("avx512f" not in cpu_flags(), reason="only a CPU with AVX-512 runs code above the cap")
def test_a_pin_after_numpy_or_opencv_loaded_raises():
    late = ("import {lib}\nfrom tactilepipe.core import vector_dispatch as v\ntry:\n    v.pin()\n"
            "except RuntimeError as exc:\n    print(exc)\nelse:\n    print('no error')")
    out = _process(late.format(lib="numpy")).stdout
    assert out.startswith("vector_dispatch.pin() called after numpy loaded: NumPy already run(s) code above AVX2")
    # OpenCV loads NumPy: NumPy capped from the start, OpenCV not
    numpy_capped = {"NPY_DISABLE_CPU_FEATURES": vector_dispatch.NUMPY_ABOVE_AVX2}
    out = _process(late.format(lib="cv2"), numpy_capped).stdout
    assert out.startswith("vector_dispatch.pin() called after numpy and cv2 loaded: OpenCV already run(s)"), out
    # pinned first, a second call after the libraries loaded is fine
    first = "from tactilepipe.core import vector_dispatch as v\nv.pin()\nimport numpy, cv2\nprint(sorted(v.pin()))"
    assert _run(first) == ["['NPY_DISABLE_CPU_FEATURES',", "'OPENBLAS_CORETYPE',", "'OPENCV_CPU_DISABLE']"]
    # a value the user set is theirs: a late call does not second-guess it
    assert _run(late.format(lib="numpy"), {"NPY_DISABLE_CPU_FEATURES": "AVX512_SPR"}) == ["no", "error"]


