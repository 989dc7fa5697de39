"""The file-read audit's reading of strace logs (tests/support/read_audit.py): which process runs
which stage, also when strace splits a call around another process's lines."""

from __future__ import annotations

from support import read_audit as ra

LOG = """\
100 execve("/usr/bin/snakemake", ["snakemake"], 0x1 /* 3 vars */) = 0
100 clone(child_stack=NULL, flags=CLONE_VM|CLONE_VFORK <unfinished ...>
200 execve("/venv/bin/python3", ["/venv/bin/python3", "-m", "tactilepipe", "papillarray-ingest", "--override", "{\\"a\\": [\\"x\\"]}", "in.bag"], 0x2 /* 5 vars */) = 0
100 <... clone resumed>) = 200
200 openat(AT_FDCWD, "raw/in.bag", O_RDONLY|O_CLOEXEC) = 3
200 clone(child_stack=NULL, flags=CLONE_VM) = 201
201 openat(AT_FDCWD, "raw/other.bag", O_RDONLY) = 4
201 openat(AT_FDCWD, "results/out.tmp", O_WRONLY|O_CREAT|O_TRUNC, 0666) = 5
201 rename("results/out.tmp", "results/out.parquet") = 0
201 openat(AT_FDCWD, "results/out.parquet", O_RDONLY) = 6
200 openat(AT_FDCWD, "raw/missing.bag", O_RDONLY) = -1 ENOENT (No such file or directory)
"""


def test_a_stage_keeps_its_reads_when_its_start_is_logged_before_the_clone_returns(tmp_path):
    (tmp_path / "raw").mkdir()
    (tmp_path / "results").mkdir()
    for name in ("raw/in.bag", "raw/other.bag", "results/out.parquet"):
        (tmp_path / name).write_text("x")
    log = tmp_path / "log"
    log.write_text(LOG)
    reads = ra.stage_reads(ra.parse(log), tmp_path)
    assert reads == {("papillarray-ingest", "--override", '{"a": ["x"]}', "in.bag"): {"raw/in.bag", "raw/other.bag"}}
