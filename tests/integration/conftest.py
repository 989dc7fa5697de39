"""The smoke build that the integration tests share: the whole pipeline at the smoke scale, built
from nothing once per test session by the real Snakemake command line.

Tests that only read it (or only plan with `snakemake -n`) use it in place. A test that changes
the project works on a copy: `shutil.copytree` (its own files, for runs that write) or
hard links (`linked_copy` in test_workflow.py, for dry runs)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from support.project import build, copy_project
from support.read_audit import audited_snakemake, strace_available


@pytest.fixture(scope="session")
def smoke_build(tmp_path_factory) -> Path:
    """Built under the file-read audit where strace is installed (tests/integration/test_read_audit.py
    reads its records; the build itself is the same)."""
    wd = tmp_path_factory.mktemp("smoke_build") / "project"
    wd.mkdir()
    copy_project(wd, scale="smoke")
    if strace_available():
        audited_snakemake(wd, "--workflow-profile", "workflow/profiles/default")
    else:
        build(wd)
    yield wd
    shutil.rmtree(wd.parent, ignore_errors=True)     # recordings, shards, models and the audit records: tens of MB
