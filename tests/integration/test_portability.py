"""The tool models' bytes travel: the smoke build's runs equal results/portability.json on this
machine (a new real machine kind is added to it); within one machine, capped instruction sets and
other thread counts train the same bytes with portable kernels but not with native ones, so the
comparison can fail; and under QEMU, as an Intel Haswell and an AMD EPYC-Rome (AVX2, no AVX-512),
the full model retrained with portable kernels is the recorded bytes (the two emulated kinds are
recorded), while native kernels under the same emulation give others."""

from __future__ import annotations

import hashlib
import json
import resource
import subprocess
from pathlib import Path

import pytest

from support.emulation import SUITE_CPUS, emulated_kind, emulator, require_qemu, under
from support.project import BIN, ENV, REPO, SMOKE, results
from tactilepipe.core.errors import TactilepipeError
from tactilepipe.tool.report import portability

RECORD = REPO / "results" / "portability.json"


def test_the_smoke_runs_are_the_recorded_bytes_on_this_machine(smoke_build: Path):
    notes = portability.check(results(smoke_build), RECORD)      # raises, naming runs and CPUs, on a difference
    record = json.loads(RECORD.read_text())
    assert any(m["kind"] == portability.machine_kind() and m["execution"] == "real" for m in record["machines"])
    assert len(record["runs"]) >= 24 and "runs identical to the record" in notes[0]
    print(notes[0])


def test_a_changed_run_is_named_with_both_machines(smoke_build: Path, tmp_path: Path):
    record = json.loads(RECORD.read_text())
    record["machines"] = [{**record["machines"][0], "kind": {**record["machines"][0]["kind"], "cpu": "Other CPU"}}]
    record["runs"]["tool_shear/no_ref"]["predictions"] = "0" * 64
    (tmp_path / "r.json").write_text(json.dumps(record))
    with pytest.raises(TactilepipeError) as err:
        portability.check(results(smoke_build), tmp_path / "r.json")
    msg = str(err.value)
    assert "tool_shear/no_ref: predictions differ" in msg and "Other CPU" in msg
    assert portability.describe(portability.machine_kind()) in msg
    assert json.loads((tmp_path / "r.json").read_text())["machines"] == record["machines"]     # nothing added

    record = json.loads(RECORD.read_text())
    record["recipe"]["digest"] = "another"
    record["recipe"]["parts"]["tool_normal"]["params"]["seed"] = 1
    (tmp_path / "r.json").write_text(json.dumps(record))
    with pytest.raises(TactilepipeError, match="recorded for another recipe .*tool_normal: params"):
        portability.check(results(smoke_build), tmp_path / "r.json")


def test_an_emulated_kind_is_recorded_only_with_the_recorded_bytes(smoke_build: Path, tmp_path: Path):
    record = json.loads(RECORD.read_text())
    (tmp_path / "r.json").write_text(json.dumps(record))
    kind = {**portability.machine_kind(), "cpu": "Emulated CPU"}
    qemu = {"program": "qemu-x86_64", "version": "7.2.22", "cpu": "Haswell-v4"}
    wrong = {"tool_normal/full": {**record["runs"]["tool_normal/full"], "weights": "0" * 64}}
    with pytest.raises(TactilepipeError, match="tool_normal/full: weights differ") as err:
        portability.check_emulated(results(smoke_build), tmp_path / "r.json", wrong, kind, qemu)
    assert "Emulated CPU" in str(err.value) and "emulated by qemu-x86_64 7.2.22 -cpu Haswell-v4" in str(err.value)
    assert json.loads((tmp_path / "r.json").read_text())["machines"] == record["machines"]     # nothing added

    right = {"tool_normal/full": record["runs"]["tool_normal/full"]}
    assert "added" in portability.check_emulated(results(smoke_build), tmp_path / "r.json", right, kind, qemu)[0]
    added = json.loads((tmp_path / "r.json").read_text())["machines"][-1]
    assert added["execution"] == "emulated" and added["emulator"] == qemu and added["runs"] == ["tool_normal/full"]
    assert "is listed" in portability.check_emulated(results(smoke_build), tmp_path / "r.json", right, kind, qemu)[0]

    record["machines"][0].pop("execution")                      # a record must say how each kind was met
    (tmp_path / "r.json").write_text(json.dumps(record))
    with pytest.raises(TactilepipeError, match="machines.0. says neither execution"):
        portability.check(results(smoke_build), tmp_path / "r.json")


def _retrain(build: Path, out: Path, kernels: str, env: dict, num_threads: int = 1,
             prefix: tuple[str, ...] = ()) -> dict:
    """The digests of the weights and predictions of the smoke build's full model on its trial split
    (the record's EMULATED_RUN), trained again by the real stage under ``env`` (and ``prefix``: an
    emulator's command)."""
    override = {"tool_train": {"kernels": kernels, "num_threads": num_threads}}
    cmd = [*prefix, str(BIN / "tactilepipe"), "tool-train", "--scale", "smoke", "--override", json.dumps(override),
           "--scene", "tool_normal", "--run", "full", "--data-dir", f"{SMOKE}/tool_normal/data",
           "--split", f"{SMOKE}/tool_normal/splits/trial.json", "--out-dir", str(out), "--quiet"]
    inherited = {k: v for k, v in ENV.items() if k not in EMULATED_VARIABLES}    # the caller's shell emulates nothing
    proc = subprocess.run(cmd, cwd=build, capture_output=True, text=True,
                          env={**inherited, "PYTHONPATH": str(build / "src"), **env})
    assert proc.returncode == 0, proc.stderr[-2000:]
    return {"weights": portability.weights_digest(out / "best.pt"),
            "predictions": portability.predictions_digest(out / "predictions.parquet")}


def _train(build: Path, out: Path, kernels: str, env: dict, num_threads: int = 1) -> str:
    """One sha256 over the weights and predictions of ``_retrain``."""
    digests = _retrain(build, out, kernels, env, num_threads)
    return hashlib.sha256((digests["weights"] + digests["predictions"]).encode()).hexdigest()


# each stands in for another kind of CPU: an older or narrower instruction set, or another thread count
EMULATIONS = {
    "ATen without vector code": {"ATEN_CPU_CAPABILITY": "default"},
    "oneDNN capped to SSE4.1": {"ONEDNN_MAX_CPU_ISA": "SSE41"},
    "MKL capped to AVX2": {"MKL_ENABLE_INSTRUCTIONS": "AVX2"},
    "2 OpenMP/MKL threads": {"OMP_NUM_THREADS": "2", "MKL_NUM_THREADS": "2"},
}
EMULATED_VARIABLES = {k for env in EMULATIONS.values() for k in env}


@pytest.mark.slow
def test_emulated_cpus_train_the_same_bytes_with_portable_kernels_only(smoke_build: Path, tmp_path: Path):
    base = _train(smoke_build, tmp_path / "portable", "portable", {})
    for name, env in EMULATIONS.items():
        assert _train(smoke_build, tmp_path / f"portable {name}", "portable", env) == base, \
            f"portable kernels gave other bytes with {name} ({env})"

    native = _train(smoke_build, tmp_path / "native", "native", {})
    assert native != base
    moved = [name for name, env in EMULATIONS.items()
             if _train(smoke_build, tmp_path / f"native {name}", "native", env) != native]
    if _train(smoke_build, tmp_path / "native 2 threads", "native", {}, num_threads=2) != native:
        moved.append("2 intra-op threads")
    print("native kernels moved under:", ", ".join(moved))
    assert "oneDNN capped to SSE4.1" in moved, moved       # the emulation can tell kernels apart


def test_portable_kernels_refuse_more_than_one_thread(smoke_build: Path, tmp_path: Path):
    override = {"tool_train": {"kernels": "portable", "num_threads": 2}}
    proc = subprocess.run([str(BIN / "tactilepipe"), "tool-train", "--scale", "smoke", "--override",
                           json.dumps(override), "--scene", "tool_normal", "--run", "full",
                           "--data-dir", f"{SMOKE}/tool_normal/data", "--split", f"{SMOKE}/tool_normal/splits/trial.json",
                           "--out-dir", str(tmp_path / "o"), "--quiet"],
                          cwd=smoke_build, capture_output=True, text=True,
                          env={**ENV, "PYTHONPATH": str(smoke_build / "src")})
    assert proc.returncode == 2
    assert "num_threads 2 with kernels: portable" in proc.stderr and "Traceback" not in proc.stderr


def _predict(build: Path, kernels: str, env: dict) -> tuple[list[str], str]:
    """The smoke full model's estimates on one simulated trial, by the real `predict` under ``env``;
    and its summary line."""
    trial = next(p for p in sorted((build / "raw/tool/sim-smoke").iterdir()) if p.name.endswith("normal00"))
    cmd = [str(BIN / "tactilepipe"), "predict", "--scale", "smoke", "--override",
           json.dumps({"predict": {"kernels": kernels}}), "--checkpoint", f"{SMOKE}/tool_normal/models/full/best.pt",
           "--trial", str(trial)]
    inherited = {k: v for k, v in ENV.items() if k not in EMULATED_VARIABLES}
    proc = subprocess.run(cmd, cwd=build, capture_output=True, text=True,
                          env={**inherited, "PYTHONPATH": str(build / "src"), **env})
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.splitlines()
    return [line.split(",")[4] for line in lines[1:-1]], lines[-1]


@pytest.mark.slow
def test_portable_predictions_are_the_same_on_emulated_cpus(smoke_build: Path):
    base, summary = _predict(smoke_build, "portable", {})
    assert "portable kernels" in summary and len(base) > 10 and len(set(base)) > 1
    for name, env in EMULATIONS.items():
        assert _predict(smoke_build, "portable", env)[0] == base, f"portable predict moved with {name} ({env})"
    assert "native kernels" in _predict(smoke_build, "native", {})[1]


EMULATED_RUN = "tool_normal/full"       # the subset of the smoke runs retrained under QEMU: 20-45 s each there


def _cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


@pytest.mark.slow
def test_emulated_intel_and_amd_cpus_train_the_recorded_bytes(smoke_build: Path, tmp_path: Path):
    qemu = require_qemu()
    recorded = json.loads(RECORD.read_text())["runs"][EMULATED_RUN]
    inherited = {k: v for k, v in ENV.items() if k not in EMULATED_VARIABLES}
    for cpu in SUITE_CPUS:            # Haswell-v4; with TACTILEPIPE_QEMU_CPUS=all EPYC-Rome too
        start = _cpu_seconds()
        kind = emulated_kind(qemu, cpu, {**inherited, "PYTHONPATH": str(smoke_build / "src")})
        # the emulation presents another CPU than any real kind recorded: AVX2 and FMA, no AVX-512
        assert {"avx2", "fma"} <= set(kind["vector_extensions"]) and "avx512f" not in kind["vector_extensions"], kind
        out = tmp_path / f"portable {cpu}"
        runs = {EMULATED_RUN: _retrain(smoke_build, out, "portable", {}, prefix=tuple(under(qemu, cpu)))}
        kind["torch_cpu_capability"] = json.loads((out / "eval.json").read_text())["kernels"]["aten_capability"]
        notes = portability.check_emulated(results(smoke_build), RECORD, runs, kind, emulator(qemu, cpu))
        native = _retrain(smoke_build, tmp_path / f"native {cpu}", "native", {}, prefix=tuple(under(qemu, cpu)))
        assert native["weights"] != recorded["weights"], \
            f"native kernels under {cpu} gave the recorded bytes: this emulation cannot tell kernels apart"
        print(f"{cpu}: {notes[0]}; native weights {native['weights'][:12]}; {_cpu_seconds() - start:.0f} CPU-s")
    machines = json.loads(RECORD.read_text())["machines"]
    emulated = {m["kind"]["vendor"] for m in machines if m["execution"] == "emulated" and EMULATED_RUN in m["runs"]}
    assert emulated >= {"GenuineIntel", "AuthenticAMD"}, machines
