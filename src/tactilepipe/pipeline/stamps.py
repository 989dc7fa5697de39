"""Parameter stamps, results/<build>/params/<stage>.json: the values a pipeline stage is given.

The workflow writes a stage's stamp (its declared keys and the keys the rules read to shape its
jobs, with their values) and rewrites it only when the values change; the stage, run by a rule
with ``--stamp``, reads its values back from it; the dvc.yaml generator reads the keys. The
format is written and read here only.
"""

from __future__ import annotations

import json
from pathlib import Path

from tactilepipe.core.config import declared, deep_merge
from tactilepipe.core.errors import InputError


def stamp_text(stage: str, keys: tuple[str, ...], graph_keys: tuple[str, ...], resolved: dict) -> str:
    """The stamp of ``stage``: the values of ``keys`` and ``graph_keys`` in the resolved parameters."""
    plain = lambda d: json.loads(json.dumps(d))
    values = deep_merge(plain(declared(resolved, keys, stage)), plain(declared(resolved, graph_keys, "workflow")))
    stamp = {"stage": stage, "declared": list(keys), "graph": list(graph_keys), "values": values}
    return json.dumps(stamp, indent=1, sort_keys=True) + "\n"


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
