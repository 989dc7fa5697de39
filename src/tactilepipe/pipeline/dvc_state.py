"""DVC's record of what Snakemake built: one state for both tools.

dvc.yaml's stages each run Snakemake targets (workflow/scripts/dvc_yaml.py). A build made with
`snakemake` (or `make run`) outside DVC leaves dvc.lock without it, so `dvc status` would call
every stage changed and `dvc repro` would build the whole hour again. After a successful run the
workflow therefore records each stage whose targets the run brought up to date, as `dvc commit`
does: the hashes of its deps, params and outs go into dvc.lock and its outs into DVC's cache
(ready for `dvc push`). Only what the run made is recorded, so a stale stage stays stale to DVC.

A run that found nothing to do records only the stages whose lock is older than what it records
(dvc.yaml, params.yaml, a file the stage depends on) or that dvc.lock lacks: Snakemake had nothing
to do, yet DVC's record is behind (an edit to a rule file's comment, a regenerated dvc.yaml, a
build made before this record existed). A few file times, so the no-op run stays quick.

Nothing is recorded when the run is not the build dvc.yaml describes or DVC is already in charge:
- inside `dvc repro` (DVC sets DVC_STAGE for a stage's command, and records the stage itself);
- with `--config` overrides (another scale or build: dvc.yaml describes params.yaml's);
- in a folder that is not a DVC project.
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
from pathlib import Path
from typing import Callable, Iterable

from tactilepipe.core.errors import TactilepipeError
from tactilepipe.core.yamlsafe import load_yaml_file

COMMAND_END = "--workflow-profile"   # a stage's command: snakemake <options> --workflow-profile <dir> <targets>


def stage_targets(root: Path, scale: str) -> dict[str, list[str]]:
    """Each dvc.yaml stage's Snakemake targets (files, or the names of target rules), at ``scale``."""
    stages = load_yaml_file(root / "dvc.yaml").get("stages") or {}
    targets = {}
    for name, stage in stages.items():
        argv = shlex.split(str(stage.get("cmd", "")).replace("${scale}", scale))
        if not argv or argv[0] != "snakemake" or COMMAND_END not in argv:
            continue                  # a stage that is not a Snakemake call is DVC's own business
        targets[name] = argv[argv.index(COMMAND_END) + 2:]
    return targets


def stages_made(targets: dict[str, list[str]], made: set[str], files_of: Callable[[str], Iterable[str]]) -> list[str]:
    """The stages all of whose targets are among the files the run made or found current.
    ``files_of(target)`` gives the files a target stands for (a rule: its inputs)."""
    return [stage for stage, names in targets.items()
            if names and all(f in made for name in names for f in files_of(name))]


def stale_stages(root: Path, stages: list[str]) -> list[str]:
    """Of ``stages``, those dvc.lock lacks or whose lock is older than dvc.yaml, params.yaml or a file
    they depend on (folders are data: a change there re-runs Snakemake jobs, which record the stage)."""
    lock = root / "dvc.lock"
    if not lock.exists():
        return list(stages)
    locked = load_yaml_file(lock).get("stages") or {}
    since = lock.stat().st_mtime_ns
    declared = load_yaml_file(root / "dvc.yaml").get("stages") or {}

    def newer(path: Path) -> bool:
        return path.is_file() and path.stat().st_mtime_ns > since

    common = newer(root / "dvc.yaml") or newer(root / "params.yaml")
    return [s for s in stages if s not in locked or common
            or any(newer(root / str(d)) for d in declared.get(s, {}).get("deps", []))]


def why_not_recorded(root: Path, overrides: dict, environ: dict) -> str | None:
    """Why this run's state is not for DVC to record, or None."""
    if environ.get("DVC_STAGE"):
        return ""                    # DVC runs this stage and writes its lock itself: nothing to say
    if not (root / ".dvc").is_dir() or not (root / "dvc.yaml").is_file():
        return ""                    # not a DVC project (a test's copy, a bare checkout)
    if overrides:
        keys = ", ".join(sorted(overrides))
        return f"DVC: not recorded: --config ({keys}) builds something other than the dvc.yaml of params.yaml"
    return None


def record(root: Path, stages: list[str], dvc: str, say: Callable[[str], None] = lambda line: None) -> str:
    """`dvc commit` the stages; the one line to show the user. Raises TactilepipeError on failure."""
    if not stages:
        return "DVC: no stage of dvc.yaml was built whole by this run; nothing recorded"
    say(f"DVC: recording {', '.join(stages)} (hashing and caching their outputs)")
    proc = subprocess.run([dvc, "commit", "--force", "--quiet", *stages], cwd=root, capture_output=True, text=True)
    if proc.returncode != 0:
        last = (proc.stderr.strip() or proc.stdout.strip() or "no message").splitlines()[-1]
        raise TactilepipeError(f"DVC: `dvc commit {' '.join(stages)}` failed: {last}")
    return f"DVC: recorded {len(stages)} stage(s) in dvc.lock and the cache: {', '.join(stages)}"


def record_run(root: Path, scale: str, made: set[str], files_of: Callable[[str], Iterable[str]],
               overrides: dict, environ: dict, say: Callable[[str], None] = lambda line: None,
               only_if_stale: bool = False) -> str:
    """Everything above for one finished Snakemake run; the line to print ('' for none)."""
    reason = why_not_recorded(root, overrides, environ)
    if reason is not None:
        return reason
    stages = stages_made(stage_targets(root, scale), made, files_of)
    if only_if_stale:
        stages = stale_stages(root, stages)
        if not stages:
            return ""
    dvc = str(Path(sys.executable).with_name("dvc"))
    return record(root, stages, dvc if Path(dvc).exists() else "dvc", say)


def after_run(scale: str, jobs, is_rule: Callable[[str], bool], get_rule, overrides: dict,
              only_if_stale: bool = False) -> None:
    """The workflow's hook after a successful run, in the project folder: ``jobs`` are the finished
    graph's (each with its ``output`` files), a target rule stands for its input files. Records the
    stages and says so on stderr."""
    def say(text: str) -> None:
        print(text, file=sys.stderr, flush=True)

    made = {str(f) for job in jobs for f in job.output}
    def files_of(target: str) -> list[str]:
        return [str(f) for f in get_rule(target).input] if is_rule(target) else [target]

    try:
        line = record_run(Path.cwd(), scale, made, files_of, overrides, os.environ, say, only_if_stale)
    except TactilepipeError as exc:
        line = f"{exc} (run it by hand once the cause is fixed)"
    if line:
        say(line)
