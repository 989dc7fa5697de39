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
