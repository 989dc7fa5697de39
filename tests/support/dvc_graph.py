"""dvc.yaml read the way DVC reads it: {stage: cmd, deps, outs} with ${key} interpolated, and
whether a path lies under a declared dep or out."""

from __future__ import annotations

import re
from pathlib import Path

import yaml


def _entries(items) -> list[str]:
    return [next(iter(i)) if isinstance(i, dict) else i for i in items or []]


def dvc_stages(dvc_yaml: Path, params: dict) -> dict[str, dict]:
    """{stage: {cmd, deps, outs}} with ${key} interpolated from params.yaml (as DVC does)."""
    def interp(s: str) -> str:
        return re.sub(r"\$\{([^}]+)\}", lambda m: str(params[m.group(1)]), s)
    stages = yaml.safe_load(dvc_yaml.read_text())["stages"]
    return {name: {"cmd": interp(" ".join(s["cmd"].split())) if isinstance(s["cmd"], str) else s["cmd"],
                   "deps": [interp(d) for d in _entries(s.get("deps"))],
                   "outs": [interp(o) for o in _entries(s.get("outs")) + _entries(s.get("metrics"))]}
            for name, s in stages.items()}


def covers(path: str, declared: str) -> bool:
    return path == declared or path.startswith(declared.rstrip("/") + "/")
