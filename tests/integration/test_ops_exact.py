"""Every op of the portable training path gives the same bytes on other CPUs, op by op.

``support/ops_probe.py`` runs the tool model's training step, BatchNorm recalibration, validation
and prediction forwards with portable kernels at the default scale's input (16 px) and width (32;
with TACTILEPIPE_QEMU_CPUS=all the paper's 64 too, as `make test-all` runs it) and hashes the outputs of each ATen op in the order they ran: the initialisation's
random draws, the padding around the fixed-order convolutions, batch norm's statistics and backward,
the GAM's sigmoid, ReLU, max pooling, the average pool, the L1 loss and its gradient, the fused
Adam step. The host and QEMU's Intel Haswell and AMD EPYC-Rome must give every op the same bytes (the
convolutions and linear layers are the project's fixed-order products, outside ATen, whose bytes
tests/unit/test_fixed_order.py checks under the same CPUs).

A library routine whose bytes depend on the vendor's code path shows up here before the smoke
record would notice it (the smoke model's small tensors may not reach that path): the probe's
extra entries, an Adam update written with ``torch.sqrt`` on a large tensor, differ between the
host and the emulated CPUs, and the same comparison reports them.

The batch: QEMU computes each vector float instruction in software, about 40 MFLOP/s, so the
default scale's batch of 64 costs about 10 CPU-minutes per emulated CPU. The suite runs the same
ops, widths and input at a batch of 4; ``TACTILEPIPE_OPS_BATCH=64`` runs the full batch
(benchmarks/record.md, "Op-by-op probe", has both measured)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from support.emulation import SUITE_CPUS, SUITE_WIDTHS, require_qemu, under
from support.project import ENV, REPO

pytestmark = pytest.mark.slow

PROBE = Path(__file__).resolve().parents[1] / "support" / "ops_probe.py"
BATCH = os.environ.get("TACTILEPIPE_OPS_BATCH", "4")
PROBE_ARGS = ("--widths", SUITE_WIDTHS, "--batch", BATCH, "--image-size", "16", "--unpinned-sqrt")
# ops of each part of the path: the probe must have seen them, or it no longer watches that part
# The convolutions and linear layers run the project's fixed-order products, im2col and col2im
# (tool/model/fixed_order.py), outside ATen: tests/unit/test_fixed_order.py requires the products'
# bytes under the same emulated CPUs and the C loops' to be those of the torch ops they replace,
# and their outputs reach the ops hashed here (the bias additions, batch norm's input, the gradients).
EXPECTED_OPS = {"aten.normal_.default", "aten.native_batch_norm.default",
                "aten.native_batch_norm_backward.default", "aten.sigmoid.default", "aten.sigmoid_backward.default",
                "aten.relu_.default", "aten.threshold_backward.default", "aten.max_pool2d_with_indices.default",
                "aten.max_pool2d_with_indices_backward.default", "aten.mean.dim", "aten.sgn.default",
                "aten._fused_adam_.default", "aten.bernoulli_.float"}


def _probe(prefix: list[str]) -> dict:
    # the kernel settings come from the probe itself (portable), not from the caller's shell
    env = {k: v for k, v in ENV.items() if not k.startswith(("ATEN_", "MKL_", "OMP_", "ONEDNN_"))}
    proc = subprocess.run([*prefix, str(PROBE), *PROBE_ARGS], capture_output=True, text=True,
                          env={**env, "PYTHONPATH": str(REPO / "src")})
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout)


def differences(a: list, b: list, limit: int = 5) -> list[str]:
    """The first entries ([label, sha256], in the order the ops ran) that differ between two runs."""
    found = [f"{x[0]}: {x[1][:12]} here, {y[1][:12]} there" if x[0] == y[0] else f"{x[0]} here, {y[0]} there"
             for x, y in zip(a, b) if x != y]
    if len(a) != len(b):
        found.append(f"{len(a)} ops here, {len(b)} there")
    return found[:limit]


@pytest.fixture(scope="module")
def host() -> dict:
    return _probe([sys.executable])


# The suite probes under the Intel model (another vendor than the AMD machines met so far, about 5
# CPU-minutes); TACTILEPIPE_QEMU_CPUS=all adds EPYC-Rome (support/emulation.py).


@pytest.mark.parametrize("cpu", SUITE_CPUS)
def test_every_op_of_the_portable_path_gives_the_same_bytes_under_emulation(host: dict, cpu: str):
    qemu = require_qemu()
    ops = {label.split(" ")[-1] for label, _ in host["ops"]}
    assert EXPECTED_OPS <= ops, EXPECTED_OPS - ops
    assert {label.split(" ")[0] for label, _ in host["ops"]} == {f"w{w}" for w in SUITE_WIDTHS.split(",")}
    emulated = _probe(under(qemu, cpu))
    assert host["capability"] == emulated["capability"] == "AVX2"
    assert host["layers"] == emulated["layers"] == "fixed-order"
    assert differences(host["ops"], emulated["ops"]) == [], f"ops whose bytes differ under {cpu}"
    # the detector: an unfused Adam update through torch.sqrt is caught by the same comparison
    caught = differences(host["unpinned"], emulated["unpinned"])
    assert any(line.startswith("unpinned torch.sqrt:") for line in caught), (cpu, caught)
    print(f"{cpu}: {len(host['ops'])} ops identical ({emulated['cpu_s']:.0f} CPU-s there, {host['cpu_s']:.0f} "
          f"here); unpinned torch.sqrt differs: {caught}")
