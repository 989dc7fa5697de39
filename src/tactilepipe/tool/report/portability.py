"""``results/portability.json``: the bytes of every smoke-scale tool run, and each kind of machine
on which they came out identical.

A record holds:
- ``recipe``: what the runs were made from, apart from the code: the training stage's parameters,
  the data set and split files, torch's version. Other parameters or data make other bytes, so a
  record is only compared with a build of the same recipe. The code is left out on purpose: an
  edit that leaves the bytes alone keeps the machines verified so far, and one that changes them
  fails the check like any other difference (then start the record again: ``--new``);
- ``runs``: per ``<scene>/<run>``, the sha256 of the trained weights (every tensor of ``best.pt``'s
  state dict: name, dtype, shape and bytes) and of the test predictions (``predictions.parquet``'s
  sample indices and predicted forces);
- ``machines``: each machine kind the runs were verified on: CPU vendor, model name, family and
  model number, vector extensions, torch's native dispatch level; and how the CPU was met:
  ``execution`` "real" (every run of the build, on a real CPU of that kind) or "emulated" (a CPU
  model that an emulator presents, with its ``emulator``: program, version and CPU model, and the
  ``runs`` retrained under it; docs/decisions/0024-real-and-emulated-machine-kinds.md).

``check`` compares a smoke build with the record: a run whose bytes differ is a finding, named
with this machine and the machines that made the recorded bytes; a new real machine kind with
identical bytes is added. ``check_emulated`` does the same for runs retrained under an emulated
CPU, whose kind the process reads from the CPUID instruction (``cpuid_kind``): under a user-mode
emulator /proc/cpuinfo still describes the host.
"""

from __future__ import annotations

import hashlib
import json
import ctypes
import mmap
import platform
from datetime import date
from pathlib import Path

from tactilepipe.core.atomic import write_json
from tactilepipe.core.environment import environment, git_state, torch_cpu_capability
from tactilepipe.core.errors import InputError, TactilepipeError
from tactilepipe.core.hashing import file_sha256
from tactilepipe.tool.scenes import TOOL_SCENES

TRAIN_STAGE = "tool-train"
REAL, EMULATED = "real", "emulated"


def weights_digest(checkpoint: Path) -> str:
    # the training stage's own loader: tensors and plain containers only, so a shared results
    # folder's best.pt cannot run code when it is read
    from tactilepipe.tool.model.checkpoint import load_checkpoint
    state = load_checkpoint(checkpoint)["model"]
    h = hashlib.sha256()
    for name, tensor in state.items():
        t = tensor.detach().contiguous()
        h.update(f"{name}\0{t.dtype}\0{tuple(t.shape)}\0".encode())
        h.update(t.numpy().tobytes())
    return h.hexdigest()


def predictions_digest(predictions: Path) -> str:
    import numpy as np
    import pandas as pd
    table = pd.read_parquet(predictions, columns=["index", "pred"])
    h = hashlib.sha256(np.ascontiguousarray(table["index"].to_numpy(np.int64)).tobytes())
    h.update(np.ascontiguousarray(table["pred"].to_numpy(np.float64)).tobytes())
    return h.hexdigest()


def run_digests(results: Path) -> dict[str, dict]:
    """``{"<scene>/<run>": {"weights": sha256, "predictions": sha256}}`` of every trained run."""
    runs = {}
    for scene in TOOL_SCENES:
        models = results / scene / "models"
        for run in sorted(p for p in models.glob("*") if (p / "best.pt").is_file()) if models.is_dir() else []:
            runs[f"{scene}/{run.name}"] = {"weights": weights_digest(run / "best.pt"),
                                          "predictions": predictions_digest(run / "predictions.parquet")}
    if not runs:
        raise InputError(results, "no trained tool runs (results/<build>/<scene>/models/<run>/best.pt): build the smoke "
                                  "scale first (make smoke)")
    return runs


def recipe(results: Path) -> dict:
    """What the runs were made from (but the code), per scene, and one digest over it."""
    parts = {}
    for scene in TOOL_SCENES:
        prov_path = results / scene / "provenance.json"
        if not prov_path.is_file():
            continue
        prov = json.loads(prov_path.read_text())
        stage = prov["stages"].get(TRAIN_STAGE)
        if stage is None:
            raise InputError(prov_path, f"records no {TRAIN_STAGE} stage")
        files = sorted([*(results / scene / "data").glob("*.npy"), results / scene / "data" / "samples.parquet",
                        *(results / scene / "splits").glob("*.json")])
        parts[scene] = {"params": stage["params"],
                        "torch": prov["environment"]["packages"]["torch"],
                        "files": {f.relative_to(results / scene).as_posix(): file_sha256(f) for f in files}}
    if not parts:
        raise InputError(results, "no tool scene provenance.json: build the smoke scale first (make smoke)")
    digest = hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()
    return {"digest": digest, "parts": parts}


def machine_kind() -> dict:
    """This machine's kind: what decides which code the numerical libraries run."""
    env = environment()
    cpu = env["cpu"]
    return {"vendor": cpu.get("vendor"), "cpu": cpu["model"], "family": cpu.get("family"),
            "model": cpu.get("model_number"), "vector_extensions": cpu["vector_extensions"],
            "torch_cpu_capability": torch_cpu_capability()}


def describe(kind: dict) -> str:
    return (f"{kind['cpu']} ({kind['vendor']}, family {kind['family']} model {kind['model']}, "
            f"torch {kind['torch_cpu_capability']})")


def describe_machine(machine: dict) -> str:
    if machine["execution"] == EMULATED:
        e = machine["emulator"]
        return f"{describe(machine['kind'])}, emulated by {e['program']} {e['version']} -cpu {e['cpu']}"
    return describe(machine["kind"])


# x86-64 machine code of ``void f(uint32 leaf, uint32 subleaf, uint32 out[4])``: cpuid, registers to out
_CPUID_CODE = bytes.fromhex("53" "4989d0" "89f8" "89f1" "0fa2" "418900" "41895804" "41894808" "4189500c" "5b" "c3")
# (leaf, subleaf, register, bit) of the vector extensions, under /proc/cpuinfo's names
_CPUID_EXTENSIONS = {"avx": (1, 0, 2, 28), "fma": (1, 0, 2, 12), "avx2": (7, 0, 1, 5), "avx512f": (7, 0, 1, 16),
                     "avx512dq": (7, 0, 1, 17), "avx512cd": (7, 0, 1, 28), "avx512bw": (7, 0, 1, 30),
                     "avx512vl": (7, 0, 1, 31), "avx512_vnni": (7, 0, 2, 11), "avx_vnni": (7, 1, 0, 4),
                     "avx512_bf16": (7, 1, 0, 5)}


def cpuid(leaf: int, subleaf: int = 0) -> tuple[int, int, int, int]:
    """(eax, ebx, ecx, edx) of the CPUID instruction, as this process's CPU (real or emulated) answers."""
    if platform.machine() not in ("x86_64", "AMD64"):
        raise TactilepipeError(f"cpuid: an x86-64 instruction, and this machine is {platform.machine()}")
    page = mmap.mmap(-1, mmap.PAGESIZE, prot=mmap.PROT_READ | mmap.PROT_WRITE | mmap.PROT_EXEC)
    page.write(_CPUID_CODE)
    view = ctypes.c_char.from_buffer(page)
    function = ctypes.CFUNCTYPE(None, ctypes.c_uint32, ctypes.c_uint32, ctypes.c_void_p)(ctypes.addressof(view))
    out = (ctypes.c_uint32 * 4)()
    function(leaf, subleaf, out)
    del function, view                   # the page's buffer is exported until then
    page.close()
    return tuple(out)


def cpuid_kind(torch_cpu_capability: str | None) -> dict:
    """This process's machine kind as CPUID reports it, in ``machine_kind``'s fields: what an emulated
    CPU presents (``torch_cpu_capability`` from a run under it: torch is not loaded here)."""
    top, b, c, d = cpuid(0)
    vendor = (b.to_bytes(4, "little") + d.to_bytes(4, "little") + c.to_bytes(4, "little")).decode("ascii", "replace")
    signature = cpuid(1)[0]
    base_family, base_model = (signature >> 8) & 0xF, (signature >> 4) & 0xF
    family = base_family + ((signature >> 20) & 0xFF if base_family == 0xF else 0)
    model = base_model | (((signature >> 16) & 0xF) << 4 if base_family in (6, 0xF) else 0)
    brand = b"".join(r.to_bytes(4, "little") for leaf in (0x80000002, 0x80000003, 0x80000004) for r in cpuid(leaf))
    registers = {(leaf, sub): cpuid(leaf, sub) for leaf, sub in {(1, 0), (7, 0), (7, 1)} if leaf <= top}
    extensions = sorted(name for name, (leaf, sub, reg, bit) in _CPUID_EXTENSIONS.items()
                        if (leaf, sub) in registers and registers[leaf, sub][reg] >> bit & 1)
    return {"vendor": vendor, "cpu": brand.rstrip(b"\0").decode("ascii", "replace").strip(), "family": str(family),
            "model": str(model), "vector_extensions": extensions, "torch_cpu_capability": torch_cpu_capability}


def _recipe_changes(old: dict, new: dict) -> list[str]:
    changes = []
    for scene in sorted(set(old) | set(new)):
        a, b = old.get(scene), new.get(scene)
        if a is None or b is None:
            changes.append(f"{scene}: {'absent from the record' if a is None else 'not in this build'}")
            continue
        changes += [f"{scene}: {key}" for key in ("params", "torch") if a[key] != b[key]]
        changed = sorted(k for k in set(a["files"]) | set(b["files"]) if a["files"].get(k) != b["files"].get(k))
        if changed:
            changes.append(f"{scene}: data {', '.join(changed)}")
    return changes


def new_record(results: Path) -> dict:
    return {"recipe": recipe(results), "runs": run_digests(results),
            "machines": [{"kind": machine_kind(), "execution": REAL, "verified": date.today().isoformat(),
                          "commit": git_state()["commit"]}]}


def _same_recipe(results: Path, record: dict, record_path: Path, scenes: set[str] | None = None) -> None:
    """Raises unless the build under ``results`` was made from the record's recipe (only the parts
    of ``scenes``, when given: a run's bytes depend on its own scene's data and parameters)."""
    now = recipe(results)
    if scenes is not None:
        old = {s: record["recipe"]["parts"].get(s) for s in scenes}
        changes = _recipe_changes({s: p for s, p in old.items() if p is not None},
                                  {s: now["parts"][s] for s in scenes if s in now["parts"]})
    elif now["digest"] != record["recipe"]["digest"]:
        changes = _recipe_changes(record["recipe"]["parts"], now["parts"])
    else:
        changes = []
    if changes:
        raise TactilepipeError(f"{record_path}: recorded for another recipe ({'; '.join(changes)}), so its bytes "
                               f"cannot be compared. After a deliberate change, build the smoke scale and run "
                               f"`tactilepipe portability --new` to start the record again on this machine")


def _differences(runs: dict, recorded: dict) -> list[str]:
    problems = []
    for name in sorted(set(runs) & set(recorded)):
        differ = [what for what in ("weights", "predictions") if runs[name][what] != recorded[name][what]]
        if differ:
            problems.append(f"{name}: {' and '.join(differ)} differ "
                            + ", ".join(f"({what} {runs[name][what][:12]}, recorded {recorded[name][what][:12]})"
                                        for what in differ))
    return problems


def _load(record_path: Path) -> dict:
    if not record_path.is_file():
        raise InputError(record_path, "no portability record: start one with `tactilepipe portability --new`")
    record = json.loads(record_path.read_text())
    for i, m in enumerate(record["machines"]):
        if m.get("execution") not in (REAL, EMULATED) or (m["execution"] == EMULATED and "emulator" not in m):
            raise InputError(record_path, f"machines[{i}] says neither execution: {REAL} nor {EMULATED} with its "
                                          f"emulator")
    return record


def check(results: Path, record_path: Path) -> list[str]:
    """Compare the smoke build under ``results`` with the record at ``record_path``. Raises
    TactilepipeError on any difference; on none, adds this machine kind if the record lacks it
    (rewriting the file) and returns notes of what was done."""
    record = _load(record_path)
    here = machine_kind()
    made_on = "; ".join(describe_machine(m) for m in record["machines"])
    _same_recipe(results, record, record_path)
    runs = run_digests(results)
    problems = [f"{name}: only in the record" for name in sorted(set(record["runs"]) - set(runs))]
    problems += [f"{name}: not in the record" for name in sorted(set(runs) - set(record["runs"]))]
    problems += _differences(runs, record["runs"])
    if problems:
        raise TactilepipeError(f"the smoke-scale tool runs are not the recorded bytes on this machine, "
                               f"{describe(here)}; recorded on {made_on}:\n  " + "\n  ".join(problems)
                               + "\n(on a listed machine kind this is a change of the training code: if it was "
                                 "meant, start the record again with `tactilepipe portability --new`)")
    if any(m["kind"] == here and m["execution"] == REAL for m in record["machines"]):
        return [f"{len(runs)} runs identical to the record; this machine kind is listed"]
    record["machines"].append({"kind": here, "execution": REAL, "verified": date.today().isoformat(),
                               "commit": git_state()["commit"]})
    write_json(record_path, record)
    return [f"{len(runs)} runs identical to the record; added this machine kind: {describe(here)}"]


def check_emulated(results: Path, record_path: Path, runs: dict[str, dict], kind: dict, emulator: dict) -> list[str]:
    """Compare ``runs`` ({"<scene>/<run>": {"weights", "predictions"}}), retrained from the smoke
    build under ``results`` on a CPU that ``emulator`` ({"program", "version", "cpu"}) presents as
    ``kind`` (``cpuid_kind``), with the record. Raises TactilepipeError on a difference; on none,
    adds the emulated kind (or the runs it lacks) and returns notes of what was done."""
    record = _load(record_path)
    _same_recipe(results, record, record_path, scenes={name.split("/")[0] for name in runs})
    machine = {"kind": kind, "execution": EMULATED, "emulator": emulator}
    made_on = "; ".join(describe_machine(m) for m in record["machines"])
    problems = [f"{name}: not in the record" for name in sorted(set(runs) - set(record["runs"]))]
    problems += _differences(runs, record["runs"])
    if problems:
        raise TactilepipeError(f"tool runs retrained on {describe_machine(machine)} are not the recorded bytes; "
                               f"recorded on {made_on}:\n  " + "\n  ".join(problems))
    listed = next((m for m in record["machines"] if m["execution"] == EMULATED and m["kind"] == kind
                   and m["emulator"] == emulator), None)
    if listed is not None and set(runs) <= set(listed["runs"]):
        return [f"{len(runs)} runs identical to the record; {describe_machine(machine)} is listed"]
    if listed is None:
        listed = {**machine, "runs": []}
        record["machines"].append(listed)
    listed.update(runs=sorted(set(listed["runs"]) | set(runs)), verified=date.today().isoformat(),
                  commit=git_state()["commit"])
    write_json(record_path, record)
    return [f"{len(runs)} runs identical to the record; added {describe_machine(machine)}"]
