"""Other CPUs on this machine: QEMU's user mode (Debian's qemu-user) runs one process under another
CPU model's CPUID and instruction set. The two models stand for another vendor and another vector
width than the hosts the project has met: Intel Haswell and AMD EPYC-Rome, both AVX2 and FMA
without AVX-512."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

QEMU_CPUS = ("Haswell-v4", "EPYC-Rome")
# Each emulated run costs minutes of CPU: the suite (`make test`, CI) emulates Intel Haswell only;
# TACTILEPIPE_QEMU_CPUS=all adds AMD EPYC-Rome (`make test-all` sets it)
SUITE_CPUS = QEMU_CPUS if os.environ.get("TACTILEPIPE_QEMU_CPUS") == "all" else QEMU_CPUS[:1]
# The op-by-op probe runs the widths the portable path trains at: the default scale's 32 in the
# suite, and the paper's 64 too with TACTILEPIPE_QEMU_CPUS=all (each width is minutes under QEMU)
SUITE_WIDTHS = "32,64" if os.environ.get("TACTILEPIPE_QEMU_CPUS") == "all" else "32"


def require_qemu() -> str:
    """qemu-x86_64's path; skips the test where it is not installed, fails in CI (which installs it)."""
    qemu = shutil.which("qemu-x86_64")
    if qemu is None:
        if os.environ.get("CI"):
            pytest.fail("qemu-x86_64 is missing: .ci/run installs it (Debian's qemu-user)")
        pytest.skip("qemu-x86_64 is not installed (apt-get install qemu-user): the emulated CPUs need it")
    return qemu


def emulator(qemu: str, cpu: str) -> dict:
    """What the portability record says of an emulated CPU: program, upstream version, CPU model."""
    first = subprocess.run([qemu, "--version"], capture_output=True, text=True, check=True).stdout.splitlines()[0]
    version = re.search(r"version (\S+)", first)
    assert version, first
    return {"program": Path(qemu).name, "version": version.group(1), "cpu": cpu}


def under(qemu: str, cpu: str) -> list[str]:
    """The command prefix that runs the venv's Python under ``cpu`` (QEMU runs ELF programs, not
    scripts: the console scripts are passed to this Python)."""
    return [qemu, "-cpu", cpu, sys.executable]


def emulated_kind(qemu: str, cpu: str, env: dict) -> dict:
    """The machine kind that a process under ``cpu`` sees (CPUID; /proc/cpuinfo is the host's)."""
    code = "import json; from tactilepipe.tool.report.portability import cpuid_kind; print(json.dumps(cpuid_kind(None)))"
    proc = subprocess.run([*under(qemu, cpu), "-c", code], capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout)
