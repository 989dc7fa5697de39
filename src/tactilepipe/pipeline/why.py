"""`tactilepipe why <output>`: the jobs that would re-make an output, or that last made it, and why.

Snakemake knows why it plans a job (its dry run prints a ``reason:`` per job: missing output, an
input updated, the rule's code or params changed) and the workflow's parameter stamps say which
key moved (``<stamp>: parameters changed: key old -> new``). Code files are inputs of the rules that
run them, so an edited module is named as an updated input. When nothing would re-run, the newest
Snakemake log (.snakemake/log/) that made the output says when and why it last ran. This reads
those texts; it runs no job.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

JOB = re.compile(r"^(?:local)?rule (\w+):\s*$")
FIELD = re.compile(r"^    (\w+): (.*)$")
WHEN = re.compile(r"^\[(\w{3} \w{3} +\d+ [\d:]+ \d{4})\]$")
PARAMS_CHANGED = re.compile(r"^(\S+\.json): parameters changed: (.*)$", re.M)
SHOWN = 3                      # files named per part of a reason; the rest are counted


@dataclass
class Job:
    rule: str
    output: list[str]
    reason: str
    wildcards: str
    when: str | None             # the log's time stamp before the job (a real run's log only)


def parse_jobs(text: str) -> list[Job]:
    """The job blocks of a Snakemake dry run or log."""
    jobs, job, when = [], None, None
    for line in text.splitlines():
        if (m := WHEN.match(line)):
            when = m[1]
        elif (m := JOB.match(line)):
            job = Job(m[1], [], "", "", when)
            jobs.append(job)
        elif job is not None and (m := FIELD.match(line)):
            key, value = m.groups()
            if key == "output":
                job.output = [f.strip() for f in value.split(",") if f.strip()]
            elif key in ("reason", "wildcards"):
                setattr(job, key, value)
        elif not line.startswith("    "):
            job = None
    return jobs


def _stamp_key(path: str) -> str | None:
    """A parameter stamp's name below its folder (``volume-baseline.json``, ``tool-train/full.json``):
    a dry run plans with a scratch copy of a changed stamp (.../changed-params/<name>), the message
    names the stamp itself (results/<build>/params/<name>)."""
    m = re.search(r"(?:^|/)(?:changed-)?params/(.+\.json)$", path)
    return m[1] if m else None


def param_changes(text: str) -> dict[str, str]:
    """Parameter stamp name -> the keys whose values changed, as the workflow printed them."""
    return {_stamp_key(stamp): change for stamp, change in PARAMS_CHANGED.findall(text) if _stamp_key(stamp)}


def short_reason(reason: str, changes: dict[str, str]) -> str:
    """A reason with at most SHOWN files per part; an updated parameter stamp names its keys."""
    parts = []
    for part in filter(None, (p.strip() for p in reason.split(";"))):
        label, _, files = part.partition(": ")
        names = [f"params/{_stamp_key(f)}" if "/changed-params/" in f else f.strip()   # a dry run's scratch copy
                 for f in files.split(",") if f.strip()]
        keys = [f"{_stamp_key(f)[:-5]}: {changes[_stamp_key(f)]}" for f in names if _stamp_key(f) in changes]
        shown = ", ".join(names[:SHOWN]) + (f" and {len(names) - SHOWN} more" if len(names) > SHOWN else "")
        parts.append(f"{label}: {shown}" if names else label)
        parts += [f"parameters changed ({k})" for k in keys]
    return "; ".join(parts)


def explain(target: str, dry_run: str, logs: list[Path]) -> str:
    """What `why` prints for ``target``, from the dry run's text and the run logs (newest first)."""
    jobs, changes = parse_jobs(dry_run), param_changes(dry_run)
    if jobs:
        lines = [f"{target}: {len(jobs)} job(s) would run"]
        by_rule: dict[str, list[Job]] = {}
        for job in jobs:
            by_rule.setdefault(job.rule, []).append(job)
        for rule, group in by_rule.items():
            reasons = sorted({short_reason(j.reason, changes) for j in group})
            lines.append(f"  {rule} x{len(group)}: " + reasons[0] + (f" (and {len(reasons) - 1} other reasons)"
                                                                  if len(reasons) > 1 else ""))
        return "\n".join(lines)
    for log in logs:
        made = [j for j in parse_jobs(log.read_text(errors="replace")) if target in j.output]
        if made:
            job = made[-1]
            wildcards = f" ({job.wildcards})" if job.wildcards else ""
            return (f"{target}: up to date; last made {job.when or 'at an unlogged time'} by rule {job.rule}"
                    f"{wildcards} (log {log.name}), because: {short_reason(job.reason, {})}")
    return (f"{target}: up to date; no Snakemake log here made it (pulled or checked out by DVC, or the logs "
            f"in .snakemake/log/ were removed)")
