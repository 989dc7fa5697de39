"""Content stamps: raw recordings that changed are re-ingested whatever their modification times.

Snakemake re-runs a job whose input is newer than its output. A corrected file copied with its
old time (``cp -p``, ``rsync -t``) or a trial folder restored from an archive (``cp -a``,
``tar -x``) is not newer, so its job would not re-run. Each ingest job therefore also takes a
small stamp (one per bag or trial) listing the content hash of every raw file the job reads. The
stamp is rewritten only when a hash changes, and then gets as its time the moment the change
reached the disk: the changed files' status-change time (ctime), which the kernel sets on every
write, rename or copy and no tool can set back. So the stamp is newer than the job's output
exactly when the content changed after the output was made; a ``touch`` or a copy of the same
bytes changes no hash and rewrites nothing.

Hashing every file at every Snakemake start would cost seconds at the default scale, so the
hashes are kept per session in the user's cache folder, keyed by each file's (size, mtime,
ctime, inode): a file is hashed again only when one of them moved, which any change of content
makes happen. A cache that cannot be read or written only costs the hashing.

A stamp without an earlier one (a new checkout, a first run) gets the newest modification time
of its files: it then adds nothing to what Snakemake sees already. Stamps are state of this
machine (their times come from its file system): they are neither versioned nor shared.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
import time
from pathlib import Path

from tactilepipe.core.atomic import write_json, write_text
from tactilepipe.core.sourcecache import CACHE_DIR


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


class SessionManifest:
    """Content hashes of one session folder's files, cached between runs by (size, mtime, ctime,
    inode). ``save()`` writes the cache back when something was hashed."""

    def __init__(self, session_dir: str | Path, cache_dir: Path | None = None):
        self.root = Path(os.path.abspath(session_dir))      # not resolve(): a realpath per file costs
        self.prefix = str(session_dir).rstrip("/") + "/"     # a file named under it: its name, cut
        key = hashlib.sha256(str(self.root).encode()).hexdigest()[:24]
        self.cache_file = (cache_dir or CACHE_DIR / "content") / f"{key}.json"
        self.entries = self._load()
        self.dirty = False

    def _load(self) -> dict:
        try:
            stored = json.loads(self.cache_file.read_text())
        except (OSError, ValueError):
            return {}
        if not isinstance(stored, dict) or stored.get("root") != str(self.root) or not isinstance(stored.get("files"), dict):
            return {}
        return stored["files"]

    def file_state(self, path: str | Path) -> dict | None:
        """{"sha256", "ctime_ns", "mtime_ns"} of ``path`` (a file of this session), or None when it
        does not exist."""
        path = Path(path)
        try:
            st = path.stat()
        except FileNotFoundError:
            return None
        if not stat.S_ISREG(st.st_mode):
            return None
        name = str(path)
        rel = name[len(self.prefix):] if name.startswith(self.prefix) else os.path.relpath(os.path.abspath(path), self.root)
        key = [st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino]
        cached = self.entries.get(rel)
        if not (isinstance(cached, list) and len(cached) == 5 and cached[:4] == key):
            cached = key + [_sha256(path)]
            self.entries[rel] = cached
            self.dirty = True
        return {"sha256": cached[4], "mtime_ns": st.st_mtime_ns, "ctime_ns": st.st_ctime_ns}

    def save(self) -> None:
        if not self.dirty:
            return
        # entries of files gone from the session are dropped, so the cache follows the folder
        files = {rel: v for rel, v in self.entries.items() if (self.root / rel).is_file()}
        try:
            write_json(self.cache_file, {"root": str(self.root), "files": files})
            self.dirty = False
        except OSError:
            pass                                  # no writable cache folder: hashed again next time


def stamp_text(manifest: SessionManifest, files: list[str]) -> tuple[str, dict]:
    """The stamp of ``files`` (their names and content hashes; a missing file as null) and the
    state of each existing file."""
    states = {f: manifest.file_state(f) for f in sorted(set(map(str, files)))}
    text = json.dumps({"files": {f: s and s["sha256"] for f, s in states.items()}}, indent=1, sort_keys=True) + "\n"
    return text, states


def holds_absent(stamp: str | Path) -> bool:
    """Whether the content stamp records a file as absent (a session not yet written when the run
    planned its jobs): the workflow records such stamps again after a successful run."""
    try:
        return None in json.loads(Path(stamp).read_text())["files"].values()
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return False


def update_stamp(stamp: str | Path, manifest: SessionManifest, files: list[str], output: str | Path,
                 dry_run_copy: str | Path | None = None) -> tuple[Path, str | None]:
    """Bring the content stamp ``stamp`` of ``files``, an input of the job that writes ``output``,
    up to date: (the stamp the job takes, what changed in recorded content or None). Unchanged, it
    is left as it is, time included. Changed, it is rewritten and its time set to when the change
    reached the disk (module docstring). In a dry run (``dry_run_copy`` given) nothing is written:
    a change made after ``output`` goes to that scratch copy instead (its newer time plans the
    re-run), and a change the output already holds keeps the stamp (a path Snakemake has not seen
    would itself plan a re-run)."""
    stamp = Path(stamp)
    text, states = stamp_text(manifest, files)
    try:
        old = stamp.read_text()
        old_time = stamp.stat().st_mtime_ns
    except FileNotFoundError:
        old, old_time = None, None
    if old == text:
        return stamp, None
    new = json.loads(text)["files"]
    if old is None:
        change = None                           # a first record: nothing to explain
        when = max((s["mtime_ns"] for s in states.values() if s), default=0)
    else:
        try:
            before = json.loads(old)["files"]
        except (ValueError, KeyError, TypeError):
            before = {}
        changed = sorted(f for f in before.keys() | new.keys() if before.get(f) != new.get(f))
        # files that had no recorded content (a session the simulator had not written yet) are
        # recorded, not reported: only a change of recorded content explains a re-run
        told = [f for f in changed if before.get(f) is not None]
        change = ("content changed: " + ", ".join(told) if told else None) if changed else "unreadable stamp, rewritten"
        # a file with no recorded content is dated by its modification time, as a first record is
        # (its job's output cannot predate it, but a copy of the project gives it a new ctime)
        times = [states[f]["ctime_ns"] if before.get(f) is not None else states[f]["mtime_ns"]
                 for f in changed if states.get(f)]
        # a removed file, or a change whose ctime the file system did not move past the stamp
        # (a rename on a file system that keeps ctime), is dated now: re-run rather than miss it
        when = max(times) if times and len(times) == len(changed) and max(times) > old_time else time.time_ns()
    target = stamp
    if dry_run_copy is not None:
        try:
            made = Path(output).stat().st_mtime_ns
        except FileNotFoundError:
            made = None                         # the job runs anyway
        if made is None or when <= made:
            return stamp if old is not None else _scratch(dry_run_copy, text, when), None
        target = Path(dry_run_copy)
    write_text(target, text)
    os.utime(target, ns=(when, when))
    return target, change


def _scratch(path: str | Path, text: str, when: int) -> Path:
    write_text(path, text)
    os.utime(path, ns=(when, when))
    return Path(path)
