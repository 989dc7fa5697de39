"""After `dvc pull`: let Snakemake know the pulled results are up to date, once DVC has checked it.

Snakemake decides by file times (and, where it ran before, by checksums it recorded in
.snakemake/). A fresh clone has no such record, and DVC writes pulled files in its own order, so
Snakemake would rebuild results that are in fact current. DVC knows better: `dvc status` compares
the content of every dep (recordings, source files, rule files, parameters) and out with what
dvc.lock recorded when the results were made. Only when it finds no difference are the stages'
Snakemake targets touched (`snakemake --touch`, which also records checksums). Any difference in
a stage that dvc.lock records is printed and nothing is touched, so a real change is never hidden;
stages that were never built (not in dvc.lock) are left to Snakemake. `make pull` runs this
with `--pull`, which first fetches with `dvc pull`: when there is nothing to pull from (no
dvc.lock, no remote, an empty or missing remote, a remote without the objects dvc.lock names) it
stops with one line saying what to set up, and keeps DVC's own output in .dvc/tmp/pull.log.
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
from pathlib import Path

from tactilepipe.core.errors import TactilepipeError
from tactilepipe.core.yamlsafe import load_yaml_file
from tactilepipe.pipeline.dvc_state import COMMAND_END, stage_targets


def run(cmd: list[str]) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, capture_output=True, text=True)


PULL_LOG = Path(".dvc/tmp/pull.log")
REMOTES = "docs/dvc.md, section Remotes"


def default_remote() -> tuple[str, str] | None:
    """(name, url) of DVC's default remote, a local folder's url made absolute as DVC resolves it."""
    from dvc.repo import Repo

    config = Repo(".").config
    name = config["core"].get("remote")
    if not name or name not in config["remote"]:
        return None
    return name, str(config["remote"][name]["url"])


def pull(bin_dir: Path) -> int:
    """`dvc pull`, or one line saying why there is nothing to pull and what to set up."""
    if not Path("dvc.lock").exists():
        print("make pull: no dvc.lock, so no built stage to pull: build the results with `make run` "
              "(it writes dvc.lock), or check out a commit that has one", file=sys.stderr)
        return 1
    remote = default_remote()
    if remote is None:
        print(f"make pull: no default DVC remote is set: add one with `dvc remote add -d <name> <url>` ({REMOTES})",
              file=sys.stderr)
        return 1
    name, url = remote
    if "://" not in url and (not Path(url).is_dir() or not any(Path(url).rglob("*"))):
        state = "is empty" if Path(url).is_dir() else "does not exist"
        print(f"make pull: the DVC remote '{name}' ({url}) {state}: run `make run` and `dvc push` where the results "
              f"were built, or point '{name}' at a remote that has them: `dvc remote modify {name} url <url>` ({REMOTES})",
              file=sys.stderr)
        return 1
    proc = run([str(bin_dir / "dvc"), "pull"])
    if proc.returncode == 0:
        print(f"Pulled from the DVC remote '{name}' ({url}).")
        return 0
    PULL_LOG.parent.mkdir(parents=True, exist_ok=True)
    PULL_LOG.write_text(proc.stdout + proc.stderr)
    missing = sum("md5:" in line for line in (proc.stdout + proc.stderr).splitlines())
    what = f"lacks {missing} of the objects dvc.lock names" if missing else "could not be read"
    print(f"make pull: the DVC remote '{name}' ({url}) {what} (DVC's output: {PULL_LOG}): `dvc push` them where the "
          f"results were built, or point '{name}' at a remote that has them ({REMOTES})", file=sys.stderr)
    return 1


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pull", action="store_true", help="`dvc pull` first (what `make pull` does)")
    args = parser.parse_args(argv)
    bin_dir = Path(sys.executable).parent
    if args.pull and (code := pull(bin_dir)) != 0:
        return code
    # dvc status can only vouch for what dvc.yaml lists: it must be the graph's own
    check = run([sys.executable, str(Path(__file__).with_name("dvc_yaml.py")), "--check"])
    if check.returncode != 0:
        print(check.stdout[-3000:] + check.stderr[-3000:] + "\nNothing is marked up to date.", file=sys.stderr)
        return 1
    status = run([str(bin_dir / "dvc"), "status", "--json"])
    if status.returncode != 0:
        print(status.stdout + status.stderr, file=sys.stderr)
        return status.returncode
    changed = json.loads(status.stdout or "{}")
    lock = Path("dvc.lock")
    built = set(load_yaml_file(lock)["stages"]) if lock.exists() else set()
    stale = {stage: what for stage, what in changed.items() if stage in built}
    if stale:
        print("DVC finds these stages out of date, so nothing is marked up to date:", file=sys.stderr)
        for stage, what in stale.items():
            print(f"  {stage}: {json.dumps(what)}", file=sys.stderr)
        return 1
    scale = str(load_yaml_file("params.yaml")["scale"])
    targets_of = {name: names for name, names in stage_targets(Path("."), scale).items()
                  if name in built}   # a stage never built here has nothing to mark
    if not targets_of:
        print("No stage of dvc.lock to mark up to date.")
        return 0
    # every stage runs the same Snakemake command line up to its targets
    first = shlex.split(load_yaml_file("dvc.yaml")["stages"][next(iter(targets_of))]["cmd"].replace("${scale}", scale))
    command = first[:first.index(COMMAND_END) + 2]
    targets = [t for names in targets_of.values() for t in names]
    touch = run([str(bin_dir / "snakemake"), *command[1:], "--touch", *targets])
    if touch.returncode != 0:
        print(touch.stdout[-3000:] + touch.stderr[-3000:], file=sys.stderr)
        return touch.returncode
    print(f"DVC found every stage up to date; Snakemake now agrees ({len(targets)} targets of {len(targets_of)} stages).")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except TactilepipeError as exc:
        sys.exit(f"mark_pulled: error: {exc}")
