"""A recording whose content changed is ingested again whatever its modification time: a corrected
file copied back with its old time (`cp -p`, `rsync -t`) re-runs the ingest of that trial or bag
and only it, a `touch` of unchanged files re-runs nothing, and a dry run writes nothing
(content stamps, src/tactilepipe/pipeline/manifest.py). On a copy of the shared smoke build."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from support.project import snakemake

pytestmark = pytest.mark.integration

PROFILE = ("--workflow-profile", "workflow/profiles/default")
INGEST = ("--until", "tool_ingest", "papillarray_ingest")


def _jobs(out: str) -> set[tuple[str, str]]:
    """(rule, wildcards) of every job a dry run plans."""
    return set(re.findall(r"^(?:local)?rule (\w+):\n(?:    .*\n)*?    wildcards: (.*)$", out, flags=re.M))


def _rules(out: str) -> set[str]:
    return set(re.findall(r"^(?:local)?rule (\w+):$", out, flags=re.M)) - {"all"}


def _copy_back_with_old_time(path: Path, content: bytes, scratch: Path) -> None:
    """What a lab does with a corrected file: write it elsewhere, give it the original's time,
    and copy it over the original keeping that time (cp -p)."""
    st = path.stat()
    fixed = scratch / path.name
    fixed.write_bytes(content)
    os.utime(fixed, ns=(st.st_atime_ns, st.st_mtime_ns))
    subprocess.run(["cp", "-p", str(fixed), str(path)], check=True)
    assert path.stat().st_mtime_ns == st.st_mtime_ns and path.stat().st_size == st.st_size


def _stamps(wd: Path) -> dict[str, tuple[bytes, int]]:
    return {str(p.relative_to(wd)): (p.read_bytes(), p.stat().st_mtime_ns)
            for p in sorted((wd / ".tactilepipe/content").rglob("*.json"))}


def test_content_changed_with_its_old_time_is_ingested_again_and_only_it(smoke_build: Path, tmp_path: Path):
    wd = shutil.copytree(smoke_build, tmp_path / "wd", symlinks=True)   # a run writes: a copy of its own
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    trial = sorted(p for p in (wd / "raw/tool/sim-smoke").iterdir() if p.name.endswith("normal00"))[0]
    bag = sorted((wd / "raw/volume/sim-smoke").glob("*.bag"))[0]
    stamps = _stamps(wd)
    assert len(stamps) > 50, "every ingest job has a content stamp"
    assert _rules(snakemake(wd, *PROFILE, "-n", *INGEST).stdout) == set()      # the copy is up to date

    # a corrected force log: one ADC count one higher, same size, copied back with the old time
    log = (trial / "force.log").read_text()
    line = log.splitlines()[3]
    first, count, rest = line.split(",", 2)
    fixed_line = f"{first},{int(count) + 1},{rest}"
    assert len(fixed_line) == len(line)
    _copy_back_with_old_time(trial / "force.log", log.replace(line, fixed_line, 1).encode(), scratch)
    # a bag with one byte changed in its last message, the same way
    data = bytearray(bag.read_bytes())
    data[-10] ^= 1
    _copy_back_with_old_time(bag, bytes(data), scratch)

    dry = snakemake(wd, *PROFILE, "-n")
    jobs = _jobs(dry.stdout)
    ingests = {(rule, wc) for rule, wc in jobs if rule.endswith("_ingest")}
    assert ingests == {("tool_ingest", f"session=sim-smoke, trial={trial.name}"),
                       ("papillarray_ingest", f"scene=volume, session=sim-smoke, stem={bag.stem}")}, ingests
    assert {"tool_dataset", "volume_dataset"} <= _rules(dry.stdout)           # and what follows from them
    assert not any(r.endswith("_simulate") for r in _rules(dry.stdout))
    assert f"content changed: raw/tool/sim-smoke/{trial.name}/force.log" in dry.stderr
    assert f"content changed: raw/volume/sim-smoke/{bag.name}" in dry.stderr
    assert _stamps(wd) == stamps, "a dry run wrote a content stamp"

    # the real run ingests exactly those two again, and then nothing is left to do
    shards = {p: p.stat().st_mtime_ns for p in (wd / "results/smoke").glob("*/shards/sim-smoke/*.parquet")}
    snakemake(wd, *PROFILE, *INGEST)
    rewritten = {str(p.relative_to(wd)) for p, t in shards.items() if p.stat().st_mtime_ns != t}
    assert rewritten == {f"results/smoke/tool/shards/sim-smoke/{trial.name}.parquet",
                         f"results/smoke/volume/shards/sim-smoke/{bag.stem}.parquet"}, rewritten
    assert _rules(snakemake(wd, *PROFILE, "-n", *INGEST).stdout) == set()

    # a touch of unchanged files (other trial, other bag, and a file the rule declares) re-runs nothing
    other = sorted(p for p in (wd / "raw/tool/sim-smoke").iterdir() if p.is_dir() and p != trial)[0]
    for f in (other / "force.log", other / "meta.json", sorted((wd / "raw/volume/sim-smoke").glob("*.bag"))[1]):
        os.utime(f)
    stamps = _stamps(wd)
    again = snakemake(wd, *PROFILE, *INGEST)
    assert _rules(again.stdout + again.stderr) == set(), again.stderr[-2000:]
    assert _stamps(wd) == stamps
