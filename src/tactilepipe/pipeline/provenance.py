"""What made a scene's results: code, parameters, input sessions, packages, machine and commit.

Written as ``provenance.json`` beside each scene's ``scores.json`` and committed with it, so a diff
of two commits shows, beside a number that moved, which of these moved with it (`tactilepipe diff`
pairs draws by them). Run times are kept out of both (``runtime.json``): they change on every run
and would bury the differences that matter; `dvc metrics diff --targets <scene>/runtime.json`
shows them.
"""

from __future__ import annotations

import os
from pathlib import Path

from tactilepipe.core.atomic import write_json
from tactilepipe.core.environment import environment, git_state
from tactilepipe.core.errors import InputError
from tactilepipe.pipeline import codedeps


def dvc_hash(path: str | Path) -> str:
    """DVC's own hash of a recording session, through DVC's library (dvc_data), so that the number
    names an object in a DVC cache or remote: a file's md5, a folder's ``<md5>.dir`` (the md5 of
    its manifest of relative names and file md5s), as ``dvc add`` records them. .dvcignore is not
    read (it is no input of the stage that writes provenance.json): a pattern that excludes files
    inside a session would make the two differ."""
    from dvc_data.hashfile.build import build
    from dvc_data.hashfile.db import HashFileDB
    from dvc_objects.fs import MemoryFileSystem
    from dvc_objects.fs.local import LocalFileSystem
    path = os.path.abspath(path)
    if not os.path.exists(path):
        raise InputError(path, "recording session not found: its hash cannot be recorded")
    # dry_run: hashes only; the cache it names is in memory, and nothing is copied there
    _, _, obj = build(HashFileDB(MemoryFileSystem(), "/unused"), path, LocalFileSystem(), "md5", dry_run=True)
    return obj.hash_info.value


def scene_provenance(given: dict[str, dict], sessions: list[str | Path]) -> dict:
    """Provenance of a scene made by the stages in ``given`` ({stage: the parameter values it was
    given}) from ``sessions``."""
    return {
        "stages": {s: {"code_sha256": codedeps.stage_fingerprint(s), "params": params} for s, params in given.items()},
        "sessions": {str(s): dvc_hash(s) for s in sessions},
        "environment": environment(),
        "git": git_state(),
    }


def write_provenance(path: str | Path, given: dict[str, dict], sessions: list[str | Path]) -> dict:
    prov = scene_provenance(given, sessions)
    write_json(path, prov)
    return prov
