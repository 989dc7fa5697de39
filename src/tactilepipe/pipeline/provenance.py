"""What made a scene's results: code, parameters, input sessions, packages, machine and commit.

Written as ``provenance.json`` beside each scene's ``metrics.json`` and tracked the same way, so
`dvc metrics diff` between two commits shows, next to a number that moved, which of these moved
with it. Run times are kept out of both (``runtime.json``): they change on every run and would
bury the differences that matter; `dvc metrics diff --targets <scene>/runtime.json` shows them.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from tactilepipe.core.atomic import write_json
from tactilepipe.core.environment import environment, git_state
from tactilepipe.core.hashing import file_sha256
from tactilepipe.pipeline import codedeps


def session_hash(path: str | Path) -> str:
    """sha256 over the relative names and contents of every file of a recording session (a folder,
    or a single file), independent of file times and of the order the files were written in."""
    path = Path(path)
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    h = hashlib.sha256()
    for f in files:
        rel = f.relative_to(path).as_posix() if path.is_dir() else f.name
        h.update(f"{rel}\0{file_sha256(f)}\0".encode())
    return h.hexdigest()


def scene_provenance(given: dict[str, dict], sessions: list[str | Path]) -> dict:
    """Provenance of a scene made by the stages in ``given`` ({stage: the parameter values it was
    given}) from ``sessions``."""
    return {
        "stages": {s: {"code_sha256": codedeps.stage_fingerprint(s), "params": params} for s, params in given.items()},
        "sessions": {str(s): session_hash(s) for s in sessions},
        "environment": environment(),
        "git": git_state(),
    }


def write_provenance(path: str | Path, given: dict[str, dict], sessions: list[str | Path]) -> dict:
    prov = scene_provenance(given, sessions)
    write_json(path, prov)
    return prov
