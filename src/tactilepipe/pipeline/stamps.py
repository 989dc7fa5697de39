"""Parameter stamps, results/<build>/params/<stage>.json: the values a pipeline stage is given.

The workflow writes a stage's stamp (its declared keys and the keys the rules read to shape its
jobs, with their values) and rewrites it only when the values change; the stage, run by a rule
with ``--stamp``, reads its values back from it; the dvc.yaml generator reads the keys. The
format is written and read here only.

A training job has a stamp of its own, results/<build>/params/tool-train/<run>.json: the values
of the stage's declared keys, and under ``run`` the run's definition (tool/runs.py
``run_definition``: its variant's name and architecture, split, depth, input size). Its ``graph``
names the params.yaml keys that definition comes from. So a key only some runs read re-runs only
those, and a new variant trains only its own runs.
"""

from __future__ import annotations

import json
from pathlib import Path

from tactilepipe.core.config import declared, deep_merge
from tactilepipe.core.errors import InputError, TactilepipeError


def stamp_text(stage: str, keys: tuple[str, ...], graph_keys: tuple[str, ...], resolved: dict) -> str:
    """The stamp of ``stage``: the values of ``keys`` and ``graph_keys`` in the resolved parameters."""
    plain = lambda d: json.loads(json.dumps(d))
    values = deep_merge(plain(declared(resolved, keys, stage)), plain(declared(resolved, graph_keys, "workflow")))
    stamp = {"stage": stage, "declared": list(keys), "graph": list(graph_keys), "values": values}
    return json.dumps(stamp, indent=1, sort_keys=True) + "\n"


TRAIN_STAGE = "tool-train"
# what a run's stamp holds under "run" (tool/runs.py run_definition makes it; imported from there by no
# stage: every stage reads its stamp through this module, and would then count that code as its own)
RUN_FIELDS = ("name", "variant", "split", "depth", "image_size")


def run_values(resolved: dict, keys: tuple[str, ...], graph_keys: tuple[str, ...]) -> dict:
    """What every run of the training stage reads: the values of its declared ``keys`` but its
    ``graph_keys``, which lay out the runs (a run reads them through its definition, under ``run``),
    so that a new variant or sweep entry re-stamps no other run."""
    values = json.loads(json.dumps(declared(resolved, keys, TRAIN_STAGE)))
    for key in graph_keys:
        *parents, leaf = key.split(".")
        node = values
        for part in parents:
            node = node.get(part) if isinstance(node, dict) else None
        if isinstance(node, dict):
            node.pop(leaf, None)
    return values


def run_stamp_text(run: dict, keys: tuple[str, ...], graph_keys: tuple[str, ...], source_keys: tuple[str, ...],
                   resolved: dict) -> str:
    """The stamp of the training job of ``run`` (its definition, tool/runs.py ``run_definition``):
    the values of the stage's declared ``keys`` but its ``graph_keys`` (``run_values``), and the run;
    ``source_keys`` are where the run's values come from in params.yaml (listed for DVC, as a stage
    stamp's graph keys)."""
    values = run_values(resolved, keys, graph_keys)
    if "run" in values:
        raise TactilepipeError(f"the {TRAIN_STAGE} stage declares a parameter group named 'run', the name its "
                               f"stamps hold the run's definition under")
    stamp = {"stage": TRAIN_STAGE, "run": run["name"], "declared": list(keys), "graph": list(source_keys),
             "values": {**values, "run": run}}
    return json.dumps(stamp, indent=1, sort_keys=True) + "\n"


def run_of_stamp(path: str | Path) -> dict:
    """The run definition a training job's stamp at ``path`` holds."""
    run = stamp_values(path, TRAIN_STAGE).get("run")
    if not isinstance(run, dict) or sorted(run) != sorted(RUN_FIELDS) or not isinstance(run["variant"], dict):
        raise InputError(path, f"not a training run's stamp (its values hold no 'run' with {', '.join(RUN_FIELDS)}: "
                               f"the workflow writes one per run, results/<build>/params/{TRAIN_STAGE}/<run>.json)")
    return run


def stamp_values(path: str | Path, stage: str) -> dict:
    """The values of ``stage``'s stamp at ``path``."""
    try:
        stamp = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise InputError(path, "no such parameter stamp") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(path, f"not a parameter stamp (not JSON: {exc})") from None
    if not isinstance(stamp, dict) or stamp.get("stage") != stage or not isinstance(stamp.get("values"), dict):
        raise InputError(path, f"not the parameter stamp of {stage} (it names "
                               f"{stamp.get('stage') if isinstance(stamp, dict) else None!r})")
    return stamp["values"]


def stamp_change(old: str | None, new: str) -> str:
    """What changed between two stamps' values, key by key (why the rules that read them re-run)."""
    if old is None:
        return "new parameter stamp"
    try:
        before = json.loads(old)["values"]
    except (ValueError, KeyError):
        return "unreadable stamp, rewritten"
    a, b = _leaves(before), _leaves(json.loads(new)["values"])
    changes = [f"{k} {json.dumps(a.get(k))} -> {json.dumps(b.get(k))}" for k in sorted(a.keys() | b.keys())
               if a.get(k, ...) != b.get(k, ...)]
    return "parameters changed: " + "; ".join(changes) if changes else "declared keys changed"


def _leaves(node, prefix: str = "") -> dict:
    if isinstance(node, dict):
        return {k: v for key, sub in node.items() for k, v in _leaves(sub, f"{prefix}{key}.").items()}
    return {prefix[:-1]: node}
