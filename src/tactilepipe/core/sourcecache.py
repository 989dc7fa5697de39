"""Values computed from the package's own source, kept between runs: which modules each pipeline
stage runs (codedeps) and how many FLOPs a model takes (estimate). Every Snakemake start needs
the first, every dry run that plans training the second, and computing them costs seconds.

Each kind lives in one small JSON file in the user's cache folder. A file is valid only for the
exact source it came from: it records a digest of every file of the package, so any edit makes
it stale and the values are computed again. A cache that cannot be read or written only costs
that time."""

from __future__ import annotations

import hashlib
import json
import os
from functools import lru_cache
from pathlib import Path

from tactilepipe.core.atomic import write_json

PACKAGE_DIR = Path(__file__).resolve().parents[1]     # src/tactilepipe
CACHE_DIR = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / PACKAGE_DIR.name


@lru_cache(maxsize=None)
def source_digest() -> str:
    h = hashlib.sha256()
    for f in sorted(PACKAGE_DIR.rglob("*.py")):
        h.update(str(f.relative_to(PACKAGE_DIR)).encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


def read(kind: str) -> dict:
    """The stored entries of ``kind`` for this exact source: {} when there are none, or they came
    from other source, or the file cannot be read."""
    try:
        stored = json.loads((CACHE_DIR / f"{kind}.json").read_text())
    except (OSError, ValueError):
        return {}
    if not isinstance(stored, dict) or stored.get("digest") != source_digest():
        return {}
    entries = stored.get("entries")
    return entries if isinstance(entries, dict) else {}


def write(kind: str, entries: dict) -> None:
    """Store ``entries`` as the values of ``kind`` for this source (replacing what was stored)."""
    try:
        write_json(CACHE_DIR / f"{kind}.json", {"digest": source_digest(), "entries": entries})
    except OSError:
        pass                                  # no writable cache folder: computed again next time
