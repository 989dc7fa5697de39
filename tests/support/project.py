"""The repository, the venv's command lines and project copies: what the end-to-end tests run."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
ENV = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"}


# Where a build keeps its results (results/<build>/, a build named by its scale unless params.yaml
# names it; src/tactilepipe/pipeline/layout.py). The tests build at the smoke scale: every path into a
# test build's results goes through these, so a change of the layout is one edit here.
SMOKE = "results/smoke"


def results(wd: Path, build: str = "smoke") -> Path:
    """The results folder of ``build`` in the project at ``wd``."""
    return Path(wd) / "results" / build


def copy_project(dest: Path, scale: str | None = None) -> Path:
    for name in ("Snakefile", "params.yaml", "dvc.yaml", ".dvcignore"):
        if (REPO / name).exists():
            shutil.copy(REPO / name, dest / name)
    for name in ("workflow", "src", "studies"):
        shutil.copytree(REPO / name, dest / name, symlinks=True,
                        ignore=shutil.ignore_patterns("__pycache__", "*.egg-info", "raw", "results", "cache", "tmp"))
    if scale:
        text = (dest / "params.yaml").read_text().replace("scale: default ", f"scale: {scale} ")
        assert f"scale: {scale} " in text
        (dest / "params.yaml").write_text(text)
    return dest


def build(wd: Path) -> None:
    """The whole pipeline in a project copy, as `make run` builds it: with the default profile,
    under which Snakemake records input checksums (which later compare a touched but unchanged
    file as unchanged)."""
    snakemake(wd, "--workflow-profile", "workflow/profiles/default")


RUN_TIMEOUT_S = 1800                 # the longest command a test runs (a smoke build) takes under 10 min


def run(cmd: list[str], cwd: Path, check: bool = True) -> subprocess.CompletedProcess:
    # a project copy runs its own source (the installed package points at the repository's)
    env = {**ENV, "PYTHONPATH": str(Path(cwd) / "src")} if (Path(cwd) / "src" / "tactilepipe").is_dir() else ENV
    # a bound on every command: a tool that hangs (a DVC command once sat 26 min in a futex wait
    # under load) fails its test instead of holding the whole suite
    try:
        proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=RUN_TIMEOUT_S)
    except subprocess.TimeoutExpired as exc:
        raise AssertionError(f"{' '.join(cmd)} did not end within {RUN_TIMEOUT_S} s") from exc
    if check and proc.returncode != 0:
        raise AssertionError(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return proc


def snakemake(cwd: Path, *args: str, check: bool = True) -> subprocess.CompletedProcess:
    return run([str(BIN / "snakemake"), "--cores", "2", *args], cwd, check)


def dvc(wd: Path, *args: str, check: bool = True):
    return run([str(BIN / "dvc"), *args], wd, check)


def git(wd: Path, *args: str):
    return run(["git", *args], wd)
