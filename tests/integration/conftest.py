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


@pytest.fixture(scope="session")
def smoke_build(tmp_path_factory) -> Path:
    wd = copy_project(tmp_path_factory.mktemp("smoke_build"), scale="smoke")
    build(wd)
    yield wd
    shutil.rmtree(wd, ignore_errors=True)        # recordings, shards and models: tens of MB

