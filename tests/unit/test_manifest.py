"""Content stamps (pipeline/manifest.py): rewritten only when a recorded hash changes, dated when the
change reached the disk, never written by a dry run, and the hash cache trusted only for a file
whose size, times and inode did not move."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

from tactilepipe.pipeline.manifest import SessionManifest, update_stamp

OLD = 1_600_000_000_000_000_000                     # 2020: a time a copy tool could set back


def _session(tmp_path: Path) -> tuple[Path, Path, Path]:
    session = tmp_path / "raw" / "s1"
    (session / "t1").mkdir(parents=True)
    log = session / "t1" / "force.log"
    log.write_text("1,500\n2,501\n")
    os.utime(log, ns=(OLD, OLD))
    output = tmp_path / "shard.parquet"
    output.write_text("made")
    return session, log, output


def _manifest(session: Path, tmp_path: Path) -> SessionManifest:
    return SessionManifest(session, cache_dir=tmp_path / "cache")


def test_a_first_record_adds_nothing_and_an_unchanged_stamp_is_left_alone(tmp_path: Path):
    session, log, output = _session(tmp_path)
    stamp = tmp_path / "stamps" / "t1.json"
    path, change = update_stamp(stamp, _manifest(session, tmp_path), [str(log)], output)
    assert path == stamp and change is None
    assert stamp.stat().st_mtime_ns == OLD           # no newer than the files it records
    assert json.loads(stamp.read_text())["files"][str(log)] is not None
    os.utime(log)                                    # touched, same bytes
    path, change = update_stamp(stamp, _manifest(session, tmp_path), [str(log)], output)
    assert change is None and stamp.stat().st_mtime_ns == OLD


def test_a_change_copied_with_its_old_time_dates_the_stamp_after_the_output(tmp_path: Path):
    session, log, output = _session(tmp_path)
    stamp = tmp_path / "stamps" / "t1.json"
    update_stamp(stamp, _manifest(session, tmp_path), [str(log)], output)
    record = stamp.read_text()
    time.sleep(0.01)
    made = time.time_ns()
    os.utime(output, ns=(made, made))
    time.sleep(0.02)          # the file system's clock (ctime) runs a tick behind time.time_ns()
    log.write_text("1,500\n2,502\n")                 # same size, then the old time put back
    os.utime(log, ns=(OLD, OLD))

    scratch = tmp_path / "scratch" / "t1.json"       # a dry run: the stamp stays as it was
    path, change = update_stamp(stamp, _manifest(session, tmp_path), [str(log)], output, dry_run_copy=scratch)
    assert path == scratch and change == f"content changed: {log}"
    assert stamp.read_text() == record and stamp.stat().st_mtime_ns == OLD
    assert scratch.stat().st_mtime_ns > made

    path, change = update_stamp(stamp, _manifest(session, tmp_path), [str(log)], output)
    assert path == stamp and change == f"content changed: {log}"
    assert stamp.stat().st_mtime_ns > made and stamp.read_text() != record


def test_a_change_the_output_already_holds_is_recorded_without_a_re_run(tmp_path: Path):
    session, log, output = _session(tmp_path)
    stamp = tmp_path / "stamps" / "t1.json"
    update_stamp(stamp, _manifest(session, tmp_path), [str(log)], output)
    log.write_text("1,500\n2,503\n")                 # rewritten (by the simulator), then ingested
    time.sleep(0.01)
    os.utime(output)
    scratch = tmp_path / "scratch" / "t1.json"
    path, change = update_stamp(stamp, _manifest(session, tmp_path), [str(log)], output, dry_run_copy=scratch)
    assert path == stamp and not scratch.exists()    # a dry run keeps the stamp Snakemake knows
    update_stamp(stamp, _manifest(session, tmp_path), [str(log)], output)
    assert stamp.stat().st_mtime_ns < output.stat().st_mtime_ns


def test_the_hash_cache_is_used_only_while_the_file_is_unmoved(tmp_path: Path):
    session, log, _ = _session(tmp_path)
    m = _manifest(session, tmp_path)
    first = m.file_state(log)["sha256"]
    m.save()
    cached = _manifest(session, tmp_path)
    rel = os.path.relpath(log, session)
    cached.entries[rel][4] = "0" * 64                # a stored hash is believed while the key holds
    assert cached.file_state(log)["sha256"] == "0" * 64
    log.write_text("1,500\n2,509\n")
    os.utime(log, ns=(OLD, OLD))                     # content changed, time put back: ctime moved
    assert cached.file_state(log)["sha256"] not in (first, "0" * 64)
    assert cached.file_state(session / "missing") is None


def test_a_file_recorded_as_absent_is_dated_by_its_time_not_by_a_copy(tmp_path: Path):
    session, log, output = _session(tmp_path)
    stamp = tmp_path / "stamps" / "t1.json"
    update_stamp(stamp, _manifest(session, tmp_path), [str(session / "t1" / "later.log")], output)
    later = session / "t1" / "later.log"             # written after the stamp, then copied (new ctime)
    later.write_text("1,500\n")
    os.utime(later, ns=(OLD, OLD))
    scratch = tmp_path / "scratch" / "t1.json"
    path, change = update_stamp(stamp, _manifest(session, tmp_path), [str(later)], output, dry_run_copy=scratch)
    assert path == stamp and change is None and not scratch.exists()
    update_stamp(stamp, _manifest(session, tmp_path), [str(later)], output)
    assert stamp.stat().st_mtime_ns == OLD
