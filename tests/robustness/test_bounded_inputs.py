"""Inputs that could run code or exhaust the machine are refused in one line, through the real CLI:
a checkpoint whose pickle carries code, a params.yaml whose aliases expand without bound, a raw
file that is a device or far larger than any recording, a session name that climbs out of raw/."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from support.hostile import billion_laughs
from support.project import REPO

SRC = REPO / "src"


def tactilepipe(*args: str, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-m", "tactilepipe", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)


def one_error_line(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode != 0, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    return lines[0]


# --- a checkpoint is read as tensors and plain values only ---------------------------------------------

class _OpensAFile:
    """Unpickled, this is a call of open(marker, "w"): the file appears. Any other call could stand here."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return open, (str(self.marker), "w")


def _checkpoint_with_payload(path: Path, marker: Path) -> Path:
    torch = pytest.importorskip("torch")
    from tactilepipe.tool.model.checkpoint import CHECKPOINT_FORMAT
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save({"format": CHECKPOINT_FORMAT, "model": {"w": torch.zeros(2)}, "meta": {}, "config": {},
                "note": _OpensAFile(marker)}, path)
    return path


def test_a_results_checkpoint_carrying_code_is_refused_and_never_run(tmp_path):
    torch = pytest.importorskip("torch")
    # the payload is live: an unrestricted load runs it (deliberately, on a file made here)
    control = tmp_path / "control-marker"
    torch.load(_checkpoint_with_payload(tmp_path / "control.pt", control), weights_only=False)
    assert control.exists()

    # a shared results folder, as `tactilepipe portability` reads it: provenance, data, one run
    results, marker = tmp_path / "shared" / "smoke", tmp_path / "marker"
    scene = results / "tool_normal"
    (scene / "data").mkdir(parents=True)
    (scene / "data" / "samples.parquet").write_bytes(b"")
    (scene / "provenance.json").write_text(json.dumps({"stages": {"tool-train": {"params": {}}},
                                                       "environment": {"packages": {"torch": torch.__version__}}}))
    best = _checkpoint_with_payload(scene / "models" / "full" / "best.pt", marker)
    proc = tactilepipe("portability", "--new", "--results", str(results), "--record", str(tmp_path / "record.json"),
                       cwd=tmp_path)
    line = one_error_line(proc)
    assert line == (f"tactilepipe portability: error: {best}: refused: not a checkpoint of tensors and plain values "
                    f"(it calls io.open); a pickle like this can run code, so it is not loaded"), line
    assert not marker.exists()
    assert not (tmp_path / "record.json").exists()


# --- a params.yaml whose aliases expand without bound ---------------------------------------------------

def test_a_billion_laughs_params_file_stops_a_stage_in_one_line(tmp_path):
    (tmp_path / "params.yaml").write_text(billion_laughs())
    proc = tactilepipe("sessions", "--params", "params.yaml", cwd=tmp_path, timeout=60)
    assert proc.returncode == 2
    assert one_error_line(proc) == ("tactilepipe sessions: error: params.yaml: its anchors and aliases expand to "
                                    "more than 200,000 nodes (at line 6): refused before loading")


# --- a raw file is a regular file of a recording's size ------------------------------------------------

def _zero(path: Path) -> Path:
    """``path`` made a link to /dev/zero: endless bytes, where a whole-file read never ends."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists() or path.is_symlink():
        path.unlink()
    path.symlink_to("/dev/zero")
    return path


@pytest.mark.parametrize("replaced", ["force.log", "digit_left/frame_000003.png"])
def test_a_trial_file_linked_to_dev_zero_stops_tool_ingest_in_one_line(tmp_path, replaced):
    from support.sessions import make_native_session
    trial = make_native_session(tmp_path) / "t00"
    args = ["tool-ingest", str(trial), "--format", "native", "--params", str(REPO / "params.yaml")]
    assert tactilepipe(*args, "--out", str(tmp_path / "ok.parquet"), cwd=tmp_path).returncode == 0   # as written, it ingests
    _zero(trial / replaced)
    proc = tactilepipe(*args, "--out", str(tmp_path / "t.parquet"), cwd=tmp_path, timeout=120)
    what = "force.log" if replaced == "force.log" else "camera frame"
    assert proc.returncode == 2
    assert one_error_line(proc).startswith(f"tactilepipe tool-ingest: error: {trial / replaced}: a character device, "
                                           f"not a file: a {what} is a regular file; not read")
    assert not (tmp_path / "t.parquet").exists()


def _sparse(path: Path, size: int) -> Path:
    """A file of ``size`` bytes that takes no disk space (a hole)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as f:
        f.truncate(size)
    return path


def _readers():
    """(reader kind, the file it reads under a folder, the call reading it, its bound)."""
    from tactilepipe.core import rawfile
    from tactilepipe.drift import read_session_meta
    from tactilepipe.papillarray.bagio import read_topics
    from tactilepipe.tool.formats import public_layout, rosbag
    from tactilepipe.tool.formats.imagefile import read_image
    from tactilepipe.tool.formats.native_layout import TrialMeta, read_calibration, read_frame_index
    from tactilepipe.tool.formats.serial_log import read_serial_log
    from tactilepipe.volume.labels import read_session_labels
    return [
        ("force.log", "force.log", read_serial_log, rawfile.FORCE_LOG_MAX),
        ("camera frame", "frame_000000.png", read_image, rawfile.IMAGE_MAX),
        ("frames.csv", "frames.csv", lambda p: read_frame_index(p.parent), rawfile.TABLE_MAX),
        ("trial's meta.json", "meta.json", lambda p: TrialMeta.read(p.parent), rawfile.META_MAX),
        ("calibration file", "nano17.cal", read_calibration, rawfile.META_MAX),
        ("force file", "force_0.csv", lambda p: public_layout._parse_force(p, "normal"), rawfile.TABLE_MAX),
        ("bag's metadata sidecar", "t.meta.json", lambda p: rosbag.read_sidecar_meta(p.with_name("t.bag")),
         rawfile.META_MAX),
        ("ROS bag", "t.bag", rosbag._bag_kind, rawfile.BAG_MAX),
        ("ROS1 bag", "lift.bag", lambda p: read_topics(p, {}), rawfile.BAG_MAX),
        ("lifts.csv", "lifts.csv", lambda p: read_session_labels(p.parent), rawfile.TABLE_MAX),
        ("session.json", "session.json", read_session_meta, rawfile.META_MAX),
    ]


READER_KINDS = [r[0] for r in _readers()]


@pytest.mark.parametrize("kind", READER_KINDS)
def test_each_raw_reader_refuses_a_device_and_a_file_over_its_bound(tmp_path, kind):
    from tactilepipe.core.errors import InputError
    _, name, read, bound = next(r for r in _readers() if r[0] == kind)
    with pytest.raises(InputError, match=f"^{_zero(tmp_path / 'z' / name)}: a character device, not a file: "
                                         f"a {kind} is a regular file; not read$"):
        read(tmp_path / "z" / name)
    big = _sparse(tmp_path / "big" / name, bound + 1)
    with pytest.raises(InputError, match=f"^{big}: .*: larger than any {kind} \\(.* at most\\); not read$"):
        read(big)


def test_read_raw_bytes_reads_a_file_within_its_bound_and_refuses_folders_and_fifos(tmp_path):
    from tactilepipe.core.errors import InputError
    from tactilepipe.core.rawfile import read_raw_bytes
    (tmp_path / "ok").write_bytes(b"x" * 10)
    assert read_raw_bytes(tmp_path / "ok", 10, "log") == b"x" * 10
    with pytest.raises(InputError, match="10 bytes: larger than any log \\(9 bytes at most\\)"):
        read_raw_bytes(tmp_path / "ok", 9, "log")
    os.mkfifo(tmp_path / "fifo")                   # opened, it would wait for a writer forever
    with pytest.raises(InputError, match="a FIFO \\(named pipe\\), not a file"):
        read_raw_bytes(tmp_path / "fifo", 10, "log")
    with pytest.raises(InputError, match="a folder, not a file"):
        read_raw_bytes(tmp_path, 10, "log")
    with pytest.raises(FileNotFoundError):         # the caller says what the missing file is for
        read_raw_bytes(tmp_path / "absent", 10, "log")


# --- a session name is a plain folder name under raw/<study>/ ------------------------------------------

@pytest.mark.parametrize("key, value", [("tool_sessions", [".."]), ("volume_sessions", ["sim-{scale}", "a/b"]),
                                        ("drift_session", "."), ("tool_sessions", ["..."])])
def test_a_session_name_that_leaves_raw_is_refused_naming_the_key(tmp_path, key, value):
    proc = tactilepipe("sessions", "--params", str(REPO / "params.yaml"), "--override", json.dumps({key: value}),
                       cwd=tmp_path)
    bad = value if isinstance(value, str) else value[-1]
    where = key if isinstance(value, str) else f"{key}.{len(value) - 1}"
    assert proc.returncode == 2
    assert one_error_line(proc) == (f"tactilepipe sessions: error: {REPO / 'params.yaml'}: invalid parameter at "
                                    f"'{where}': {bad!r} is not a plain folder name under raw/<study>/: letters, "
                                    f"digits, '-', '_', '.' (not only dots), no '/'")


def test_a_plain_session_name_with_dots_is_a_name(tmp_path):
    proc = tactilepipe("sessions", "--params", str(REPO / "params.yaml"), "--override",
                       json.dumps({"tool_sessions": ["lab.2026-05-01"]}), cwd=tmp_path)
    assert "raw/tool/lab.2026-05-01: session folder not found" in proc.stderr, proc.stderr
