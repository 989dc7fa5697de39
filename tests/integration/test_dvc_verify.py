"""Corrupt stored data is caught: the project's remote re-hashes what `dvc pull` fetches, and
`tactilepipe verify-data` re-hashes the workspace where `dvc status` trusts file times."""

from __future__ import annotations

import configparser
import os

import pytest

from support.project import BIN, REPO, dvc, git, run

pytestmark = pytest.mark.integration


@pytest.fixture
def project(tmp_path):
    wd = tmp_path / "p"
    (wd / "data" / "sub").mkdir(parents=True)
    (wd / "data" / "a.bin").write_bytes(b"frame a" * 100)
    (wd / "data" / "sub" / "b.bin").write_bytes(b"frame b" * 100)
    git(wd, "init", "-q")
    git(wd, "config", "user.email", "t@example.com")
    git(wd, "config", "user.name", "t")
    dvc(wd, "init", "-q")
    dvc(wd, "remote", "add", "-d", "r", str(tmp_path / "remote"))
    dvc(wd, "remote", "modify", "r", "verify", "true")               # as the project's .dvc/config does
    dvc(wd, "add", "-q", "data")
    git(wd, "add", "-A")
    git(wd, "commit", "-q", "-m", "data")
    dvc(wd, "push", "-q")
    return wd


def test_the_project_remote_re_hashes_what_it_fetches():
    config = configparser.ConfigParser()
    config.read(REPO / ".dvc" / "config")
    assert config['\'remote "local"\'']["verify"] == "true"


def test_a_changed_file_with_a_clean_status_is_named(project):
    path = project / "data" / "sub" / "b.bin"
    st = os.stat(path)
    path.write_bytes(b"frame c" * 100)                               # same size, same time
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert "up to date" in dvc(project, "status").stdout            # what DVC alone says
    proc = run([str(BIN / "tactilepipe"), "verify-data"], project, check=False)
    assert proc.returncode == 1
    assert proc.stdout.startswith("data/sub/b.bin: content md5 ") and "2 files tracked by DVC re-hashed: 1 differ" in proc.stdout
    dvc(project, "checkout", "--relink", "-q")              # --force trusts the file time too
    assert run([str(BIN / "tactilepipe"), "verify-data"], project).returncode == 0


def test_a_corrupt_object_in_the_remote_fails_the_pull(project, tmp_path):
    obj = next(p for p in (tmp_path / "remote").rglob("*") if p.is_file() and not p.name.endswith(".dir")
               and p.read_bytes() == b"frame b" * 100)
    obj.chmod(0o644)
    obj.write_bytes(b"frame X" * 100)
    clone = tmp_path / "clone"
    git(tmp_path, "clone", "-q", str(project), str(clone))
    proc = dvc(clone, "pull", check=False)
    assert proc.returncode != 0
    bad = run([str(BIN / "tactilepipe"), "verify-data"], clone, check=False)
    assert bad.returncode == 1 and "data/sub/b.bin: missing" in bad.stdout
