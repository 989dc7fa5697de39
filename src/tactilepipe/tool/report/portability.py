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
  model number, vector extensions, torch's native dispatch level.

``check`` compares a smoke build with the record: a run whose bytes differ is a finding, named
with this machine and the machines that made the recorded bytes; a new machine kind with
identical bytes is added.
"""

from __future__ import annotations

import hashlib
import json
from datetime import date
from pathlib import Path

from tactilepipe.core.atomic import write_json
from tactilepipe.core.environment import environment, git_state
from tactilepipe.core.errors import InputError, TactilepipeError
from tactilepipe.core.hashing import file_sha256
from tactilepipe.tool.scenes import TOOL_SCENES

TRAIN_STAGE = "tool-train"


def weights_digest(checkpoint: Path) -> str:
    import torch
    state = torch.load(checkpoint, map_location="cpu", weights_only=False)["model"]
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
            "torch_cpu_capability": env["torch_cpu_capability"]}


def describe(kind: dict) -> str:
    return (f"{kind['cpu']} ({kind['vendor']}, family {kind['family']} model {kind['model']}, "
            f"torch {kind['torch_cpu_capability']})")


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
            "machines": [{"kind": machine_kind(), "verified": date.today().isoformat(),
                          "commit": git_state()["commit"]}]}


def check(results: Path, record_path: Path) -> list[str]:
    """Compare the smoke build under ``results`` with the record at ``record_path``. Raises
    TactilepipeError on any difference; on none, adds this machine kind if the record lacks it
    (rewriting the file) and returns notes of what was done."""
    if not record_path.is_file():
        raise InputError(record_path, "no portability record: start one with `tactilepipe portability --new`")
    record = json.loads(record_path.read_text())
    here = machine_kind()
    made_on = "; ".join(describe(m["kind"]) for m in record["machines"])
    now = recipe(results)
    if now["digest"] != record["recipe"]["digest"]:
        changes = _recipe_changes(record["recipe"]["parts"], now["parts"])
        raise TactilepipeError(f"{record_path}: recorded for another recipe ({'; '.join(changes)}), so its bytes "
                               f"cannot be compared. After a deliberate change, build the smoke scale and run "
                               f"`tactilepipe portability --new` to start the record again on this machine")
    runs = run_digests(results)
    problems = [f"{name}: only in the record" for name in sorted(set(record["runs"]) - set(runs))]
    problems += [f"{name}: not in the record" for name in sorted(set(runs) - set(record["runs"]))]
    for name in sorted(set(runs) & set(record["runs"])):
        differ = [what for what in ("weights", "predictions") if runs[name][what] != record["runs"][name][what]]
        if differ:
            problems.append(f"{name}: {' and '.join(differ)} differ")
    if problems:
        raise TactilepipeError(f"the smoke-scale tool runs are not the recorded bytes on this machine, "
                               f"{describe(here)}; recorded on {made_on}:\n  " + "\n  ".join(problems)
                               + "\n(on a listed machine kind this is a change of the training code: if it was "
                                 "meant, start the record again with `tactilepipe portability --new`)")
    if any(m["kind"] == here for m in record["machines"]):
        return [f"{len(runs)} runs identical to the record; this machine kind is listed"]
    record["machines"].append({"kind": here, "verified": date.today().isoformat(), "commit": git_state()["commit"]})
    write_json(record_path, record)
    return [f"{len(runs)} runs identical to the record; added this machine kind: {describe(here)}"]
