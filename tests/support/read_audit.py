"""Which files each pipeline stage reads, against what its rule declares (the file-read audit).

A build runs under strace (`traced`), which records every file any process opens, whatever opens
it: Python's open, numpy, pyarrow's and OpenCV's C++ readers, subprocesses. Each stage process
(`python -m tactilepipe ...`, with the processes it starts) is matched to its Snakemake job by its
command line (a dry run of every job lists each job's shell command and declared inputs).
A file inside the project that a stage opens for reading is declared when it is

- one of the job's inputs, or inside an input folder (a trial folder, a session); a simulated tool
  trial's folder is declared by its meta.json (the simulate job writes the folder whole and
  declares meta.json for it; nothing else writes there);
- one of the job's outputs or its log, or a file the stage wrote itself (a checkpoint it reloads);
- or on the short ALLOWED list below, each with the reason it cannot make a result stale.

Everything else is an undeclared read: editing that file would leave the job's results stale.

Source files are audited by what each stage imports rather than what it opens (the stage-code
cache reads the whole package to fingerprint it): ``import_audit/sitecustomize.py`` records every
stage process's tactilepipe modules, and each must be in the rule's declared code.
"""

from __future__ import annotations

import json
import re
import shlex
import shutil
import subprocess
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

SYSCALLS = "execve,open,openat,rename,renameat,renameat2,clone,clone3,fork,vfork"
ALLOWED = {
    "params.yaml": "parameters: each stage reads only its declared keys, tracked by the rule's parameter "
                   "stamp (results/<build>/params/<stage>.json), which is declared",
    "src/tactilepipe/core/params.schema.json": "validation of params.yaml: it accepts or refuses, never changes a value",
}
ALLOWED_PREFIXES = {
    ".git/": "provenance.json records the commit and whether code had uncommitted changes (`git`), not an input",
    "src/": "source files: audited by import (`undeclared_code`)",
}
# modules every stage imports to build the command line, whatever it runs: every study's command
# module (each imports its stage's code inside the stage's function) and what they import at their
# top, which only names choices (the tool scenes, the model variants and depths) and each study's
# parameter checks for its commands' declarations (checks=), which a stage of another study never
# calls (and under the workflow no stage calls: it reads its stamp)
PARSER_MODULES = ("src/tactilepipe/cli/", "src/tactilepipe/tool/scenes.py", "src/tactilepipe/tool/__init__.py",
                  "src/tactilepipe/tool/model/__init__.py", "src/tactilepipe/tool/model/variants.py",
                  "src/tactilepipe/tool/checks.py", "src/tactilepipe/volume/__init__.py",
                  "src/tactilepipe/volume/checks.py", "src/tactilepipe/papillarray/__init__.py",
                  "src/tactilepipe/papillarray/checks.py", "src/tactilepipe/studies.py",
                  # plain data those modules name: the model vocabulary, the simulated-session
                  # convention (volume/checks.py), the rig's modes and baud (cli/rig.py's choices)
                  "src/tactilepipe/core/tool_vocabulary.py", "src/tactilepipe/core/simulated.py",
                  "src/tactilepipe/rig/__init__.py", "src/tactilepipe/rig/settings.py")
IMPORT_AUDIT_SITE = Path(__file__).parent / "import_audit"
SIMULATED_TRIAL = re.compile(r"raw/tool/sim-[^/]+/[^/]+/meta\.json")


@dataclass
class Process:
    pid: int
    parent: int | None = None
    argv: list[str] = field(default_factory=list)
    stage: tuple[str, ...] | None = None          # the tactilepipe command it runs, or runs under
    reads: set[str] = field(default_factory=set)
    writes: set[str] = field(default_factory=set)


def strace_available() -> bool:
    return shutil.which("strace") is not None


def traced(command: list[str], log: Path) -> list[str]:
    """``command`` under strace, every process's opens and starts written to ``log``."""
    return ["strace", "-f", "-qq", "--seccomp-bpf", "-s", "8192", "-e", f"trace={SYSCALLS}", "-o", str(log), *command]


_LINE = re.compile(r"^(\d+)\s+(.*)$")
_STRING = re.compile(r'"((?:[^"\\]|\\.)*)"')
_RESULT = re.compile(r"\)\s+=\s+(-?\d+)")


def _unescape(text: str) -> str:
    return text.encode("latin-1", "backslashreplace").decode("unicode_escape").encode("latin-1").decode(
        "utf-8", "replace")


def stage_command(argv: list[str]) -> tuple[str, ...] | None:
    """The stage and its arguments of a `python -m tactilepipe ...` command line (None: another)."""
    if "-m" not in argv or argv[argv.index("-m") + 1:argv.index("-m") + 2] != ["tactilepipe"]:
        return None
    return tuple(argv[argv.index("-m") + 2:])


def parse(log: Path) -> dict[int, Process]:
    """Processes of a strace log: parent, last command line, and the files opened for reading."""
    procs: dict[int, Process] = {}
    ended: list[Process] = []                    # earlier processes whose id was reused
    pending: dict[int, str] = {}                 # a call strace split around another process's

    def proc(pid: int) -> Process:
        return procs.setdefault(pid, Process(pid))

    for raw in log.read_text(errors="replace").splitlines():
        m = _LINE.match(raw)
        if not m:
            continue
        pid, rest = int(m.group(1)), m.group(2)
        if rest.endswith("<unfinished ...>"):
            pending[pid] = rest[: -len("<unfinished ...>")]
            continue
        if rest.startswith("<..."):
            rest = pending.pop(pid, "") + rest.split("resumed>", 1)[-1]
        call = rest.split("(", 1)[0]
        result = _RESULT.search(rest)
        ret = int(result.group(1)) if result else -1
        if call in ("clone", "clone3", "fork", "vfork") and ret > 0:
            child = procs.get(ret)
            if child is not None and child.parent is None:
                # the child's own lines came first (strace split the parent's clone around them):
                # it is this child, and keeps what it did (an execve sets its own stage)
                child.parent = pid
                child.argv = child.argv or list(proc(pid).argv)
                child.stage = child.stage or proc(pid).stage
                continue
            if child is not None:
                ended.append(procs.pop(ret))     # an id used again by a new process
            proc(ret).parent = pid
            proc(ret).argv, proc(ret).stage = list(proc(pid).argv), proc(pid).stage
        elif call == "execve" and ret == 0:
            # ["arg", ...], then the environment as /* N vars */: an argument may hold "]" itself
            args = rest[rest.index("[") + 1: rest.rindex("], ")] if "[" in rest and "], " in rest else ""
            argv = proc(pid).argv = [_unescape(s) for s in _STRING.findall(args)]
            proc(pid).stage = stage_command(argv) or proc(pid).stage
        elif call in ("open", "openat") and ret >= 0:
            strings = _STRING.findall(rest)
            flags = rest.split('",', 1)[-1]
            if strings:
                writing = any(f in flags for f in ("O_WRONLY", "O_RDWR", "O_CREAT"))
                (proc(pid).writes if writing else proc(pid).reads).add(_unescape(strings[0]))
        elif call.startswith("rename") and ret == 0:
            strings = _STRING.findall(rest)
            if len(strings) >= 2:
                proc(pid).writes.add(_unescape(strings[1]))
    # a reused id's earlier process keeps its records under a key no live process has
    for k, p in enumerate(ended):
        procs[-(k + 1)] = p
    return procs


def stage_reads(procs: dict[int, Process], root: Path) -> dict[tuple[str, ...], set[str]]:
    """Files inside ``root`` each stage command (its arguments after `-m tactilepipe`) read and
    did not write itself."""
    reads: dict[tuple[str, ...], set[str]] = defaultdict(set)
    writes: dict[tuple[str, ...], set[str]] = defaultdict(set)
    root = root.resolve()
    for p in procs.values():
        if p.stage is None:
            continue
        key = p.stage
        reads[key].update(r for r in (_inside(path, root) for path in p.reads) if r is not None)
        writes[key].update(_relative(path, root) for path in p.writes)
    return {key: files - writes[key] for key, files in reads.items()}


def _relative(path: str, root: Path) -> str:
    full = Path(path) if Path(path).is_absolute() else root / path
    try:
        return full.resolve().relative_to(root).as_posix()
    except ValueError:
        return str(full)


def _inside(path: str, root: Path) -> str | None:
    """``path`` relative to the project (None outside it), .pyc files as their source file."""
    full = Path(path) if Path(path).is_absolute() else root / path
    try:
        rel = full.resolve().relative_to(root)
    except ValueError:
        return None
    if not (root / rel).is_file():
        return None                                 # folders (listed: see `undeclared`), vanished temporaries
    parts = rel.parts
    if "__pycache__" in parts and rel.suffix == ".pyc":
        rel = Path(*parts[:parts.index("__pycache__")]) / (rel.name.split(".")[0] + ".py")
    return rel.as_posix()


@dataclass
class Job:
    rule: str
    command: tuple[str, ...]
    inputs: set[str]
    outputs: set[str]


def declared_jobs(root: Path, snakemake: list[str]) -> list[Job]:
    """Every job of the project with the inputs and outputs its rule declares now: a dry run that
    plans every job (`snakemake -n -F -p`), with the project's own source on the path as when it
    built (so the code inputs are the project's files)."""
    from support.project import ENV
    env = {**ENV, "PYTHONPATH": str(root / "src")}
    proc = subprocess.run([*snakemake, "-n", "-F", "-p"], cwd=root, env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise AssertionError(f"snakemake -n -F failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    jobs, block = [], {}
    for line in (proc.stdout + proc.stderr).splitlines():
        head = re.match(r"^(?:local)?rule (\w+):$", line)
        if head:
            block = {"rule": head.group(1)}
            continue
        field_ = re.match(r"^    (input|output|log): (.*)$", line)
        if field_ and block:
            block[field_.group(1)] = set(field_.group(2).split(", "))
        elif line.startswith("Shell command: ") and block and "-m tactilepipe" in line:
            tokens = shlex.split(line[len("Shell command: "):])
            tokens = tokens[:next((i for i, t in enumerate(tokens) if t.startswith((">", "2>", "&>", "|"))), len(tokens))]
            jobs.append(Job(block["rule"], stage_command(tokens), block.get("input", set()),
                            block.get("output", set()) | block.get("log", set())))
            block = {}
    return jobs


def _covered(path: str, declared: set[str]) -> bool:
    return any(path == d or path.startswith(d.rstrip("/") + "/") for d in declared)


def undeclared(reads: dict[tuple[str, ...], set[str]], jobs: list[Job]) -> dict[str, list[str]]:
    """``{"<rule> <command>": [undeclared files read]}`` over every job that ran under the trace."""
    def declared(job: Job, f: str) -> bool:
        inputs = job.inputs | {str(Path(i).parent) for i in job.inputs if SIMULATED_TRIAL.fullmatch(i)}
        return (_covered(f, inputs) or _covered(f, job.outputs) or f in ALLOWED
                or f.startswith(tuple(ALLOWED_PREFIXES)))
    return _per_job(reads, jobs, declared)


def _per_job(found: dict[tuple[str, ...], set[str]], jobs: list[Job], declared) -> dict[str, list[str]]:
    """``{"<rule> <command>": [what the job's process used that declared(job, f) rejects]}``."""
    problems = {}
    for job in jobs:
        bad = sorted(f for f in found.get(job.command, ()) if not declared(job, f))
        if bad:
            problems[f"{job.rule}: {' '.join(job.command)[:160]}"] = bad
    return problems


def stage_imports(audit_dir: Path, root: Path) -> dict[tuple[str, ...], set[str]]:
    """Source files (relative to the project) of the tactilepipe modules each stage command imported."""
    out: dict[tuple[str, ...], set[str]] = defaultdict(set)
    root = root.resolve()
    for record in audit_dir.glob("*.json"):
        data = json.loads(record.read_text())
        key = stage_command(data["orig_argv"] or data["argv"])
        if key is None:
            continue
        for f in data["modules"]:
            try:
                out[key].add(Path(f).resolve().relative_to(root).as_posix())
            except ValueError:
                pass
    return out


def undeclared_code(imports: dict[tuple[str, ...], set[str]], jobs: list[Job]) -> dict[str, list[str]]:
    """``{"<rule> <command>": [modules imported but not in the rule's declared code]}``."""
    return _per_job(imports, jobs, lambda job, m: m in job.inputs or m.startswith(PARSER_MODULES))


@dataclass
class Audit:
    """Where an audited build left its records."""
    root: Path
    strace_log: Path
    imports: Path

    def reads(self) -> dict[tuple[str, ...], set[str]]:
        return stage_reads(parse(self.strace_log), self.root)

    def imported(self) -> dict[tuple[str, ...], set[str]]:
        return stage_imports(self.imports, self.root)


def audited_snakemake(wd: Path, *args: str) -> Audit:
    """``snakemake --cores 2 *args`` in the project ``wd`` with every stage's file reads and imports
    recorded (records beside the project: they are not the project's files)."""
    import os
    from support.project import BIN, ENV
    audit = Audit(wd, wd.parent / f"{wd.name}.strace", wd.parent / f"{wd.name}.imports")
    audit.imports.mkdir(exist_ok=True)
    env = {**ENV, "PYTHONPATH": f"{IMPORT_AUDIT_SITE}{os.pathsep}{wd / 'src'}",
           "TACTILEPIPE_IMPORT_AUDIT": str(audit.imports)}
    proc = subprocess.run(traced([str(BIN / "snakemake"), "--cores", "2", *args], audit.strace_log), cwd=wd, env=env,
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise AssertionError(f"audited snakemake {' '.join(args)} failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    return audit
