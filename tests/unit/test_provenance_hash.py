"""provenance.json names each recording session by DVC's own hash, the one `dvc add` records, so a
number in a scene's provenance names an object in the project's DVC cache and remote."""

from __future__ import annotations

import subprocess
import sys

import pytest
import yaml

from tactilepipe.core.errors import InputError
from tactilepipe.pipeline.provenance import dvc_hash, scene_provenance


def _session(root):
    """A session folder as a rig leaves it: nested files, a text file with Windows line ends
    (DVC 3 hashes the bytes as they are), an empty file, a binary."""
    folder = root / "raw" / "volume" / "lab-0301"
    (folder / "bags").mkdir(parents=True)
    (folder / "lifts.csv").write_bytes(b"bag,volume_ml,set\r\nlift_00.bag,100,train\r\n")
    (folder / "notes.txt").write_bytes(b"")
    (folder / "bags" / "lift_00.bag").write_bytes(bytes(range(256)) * 40)
    return folder


def _dvc_add(repo, name: str) -> str:
    """The md5 `dvc add` records for ``name`` in the DVC project ``repo``."""
    subprocess.run([sys.executable, "-m", "dvc", "add", "-q", name], cwd=repo, check=True)
    return yaml.safe_load((repo / f"{name}.dvc").read_text())["outs"][0]["md5"]


@pytest.fixture(scope="module")
def dvc_repo(tmp_path_factory):
    repo = tmp_path_factory.mktemp("dvcrepo")
    subprocess.run(["git", "init", "-q", str(repo)], check=True)
    subprocess.run([sys.executable, "-m", "dvc", "init", "-q"], cwd=repo, check=True)
    return repo


def test_a_sessions_hash_is_the_one_dvc_add_records(dvc_repo, tmp_path):
    folder = _session(tmp_path)
    recorded = scene_provenance({}, [folder])["sessions"][str(folder)]
    import shutil
    shutil.copytree(folder, dvc_repo / "session")
    assert recorded == _dvc_add(dvc_repo, "session")
    assert recorded.endswith(".dir")
    # a single file is its md5
    (dvc_repo / "one.bag").write_bytes(b"\x00\x01bag")
    assert dvc_hash(dvc_repo / "one.bag") == _dvc_add(dvc_repo, "one.bag")


def test_a_changed_byte_changes_the_hash_and_a_missing_session_is_named(tmp_path):
    folder = _session(tmp_path)
    before = dvc_hash(folder)
    (folder / "lifts.csv").write_bytes(b"bag,volume_ml,set\r\nlift_00.bag,101,train\r\n")
    assert dvc_hash(folder) != before
    with pytest.raises(InputError, match="recording session not found"):
        dvc_hash(tmp_path / "raw" / "volume" / "gone")
