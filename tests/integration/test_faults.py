"""Faults: the pipeline killed mid-job, a full disk, a read-only or forbidden results folder, two
Snakemakes in one folder. Each must end in a clear message and leave nothing half written; a
killed run, re-run the way the message says, must give the results of an uninterrupted run.

The Snakemake runs use the smoke scale and only the tool_normal scene (its ingest and one model
are the longest jobs of that scale). One uninterrupted run is the reference every faulted run is
compared with, byte for byte where the output is deterministic.

What a user types after a run was killed (SIGKILL, power loss, OOM killer):

    snakemake --unlock          # the killed run could not release its lock on the folder
    snakemake --cores 2 ...     # the same command again; the profile's rerun-incomplete redoes
                                # the job that was cut short, and nothing else
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pandas as pd
import pytest

from support.project import BIN, ENV, SMOKE, copy_project, results

pytestmark = pytest.mark.integration

PROFILE = ["--workflow-profile", "workflow/profiles/default"]       # as `make run` passes it
CONFIG = ["--config", "scale=smoke", "scenes=[tool_normal]"]
DATA = f"{SMOKE}/tool_normal/data/samples.parquet"
MODEL_DIR = f"{SMOKE}/tool_normal/models/full"
MODEL = f"{MODEL_DIR}/eval.json"
SHARDS = f"{SMOKE}/tool/shards/sim-smoke"
LOCKED = "Directory cannot be locked"
# eval.json fields that measure the machine, not the model
TIMING_FIELDS = {"train_s", "latency_ms", "predict_s"}


def env_of(wd: Path) -> dict:
    """Each folder runs its own copy of the package (copied with the project), so the reference
    and the faulted runs use the same code even while the working tree is being edited."""
    return {**ENV, "PYTHONPATH": str(wd / "src")}


def smk(wd: Path, *args: str, check: bool = True) -> subprocess.CompletedProcess:
    proc = subprocess.run([str(BIN / "snakemake"), "--cores", "2", *PROFILE, *args], cwd=wd, env=env_of(wd),
                          capture_output=True, text=True)
    if check and proc.returncode != 0:
        raise AssertionError(f"snakemake {' '.join(args)} failed ({proc.returncode}):\n"
                             f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return proc


def start(wd: Path, *args: str) -> subprocess.Popen:
    """Snakemake in its own process group (so the whole group, jobs included, can be killed)."""
    log = open(wd / "background.out", "w")
    return subprocess.Popen([str(BIN / "snakemake"), "--cores", "2", *PROFILE, *args], cwd=wd, env=env_of(wd),
                            stdout=log, stderr=subprocess.STDOUT, start_new_session=True)


def kill_group(proc: subprocess.Popen) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=60)


def wait_for(condition, proc: subprocess.Popen, wd: Path, timeout: float = 300.0, poll: float = 0.005):
    """Poll ``condition()`` until it returns something truthy (returned); fail if snakemake ends first."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = condition()
        if value:
            return value
        if proc.poll() is not None:
            raise AssertionError(f"snakemake ended ({proc.returncode}) before the fault could be injected:\n"
                                 + (wd / "background.out").read_text()[-3000:])
        time.sleep(poll)
    kill_group(proc)
    raise AssertionError("timed out waiting for the job to start")


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def temporaries(wd: Path) -> list[Path]:
    return sorted(p for p in (wd / "results").rglob("*") if p.name.endswith(".tmp"))


def clone(reference: Path, dest: Path, drop: list[str]) -> Path:
    """A copy of the reference folder (recordings, results, Snakemake's records) minus ``drop``."""
    shutil.copytree(reference, dest, symlinks=True)
    for rel in drop:
        shutil.rmtree(dest / rel)
    (dest / "background.out").unlink(missing_ok=True)
    return dest


def recover(wd: Path, target: str) -> subprocess.CompletedProcess:
    """What the user does after a killed run: the re-run is refused while the dead run's lock is
    there (with Snakemake's message saying to unlock), then --unlock and the same command again."""
    refused = smk(wd, *CONFIG, "--", target, check=False)
    assert refused.returncode != 0
    assert LOCKED in refused.stdout + refused.stderr and "--unlock" in refused.stdout + refused.stderr
    smk(wd, *CONFIG, "--unlock")
    return smk(wd, *CONFIG, "--", target)


def assert_same_data(wd: Path, reference: Path) -> None:
    ref_shards = sorted(p.name for p in (reference / SHARDS).glob("*.parquet"))
    assert ref_shards and sorted(p.name for p in (wd / SHARDS).glob("*.parquet")) == ref_shards
    for name in ref_shards:
        assert sha(wd / SHARDS / name) == sha(reference / SHARDS / name), name
    for name in ("samples.parquet", "frames.npy", "references.npy", "qc.json"):
        assert sha(results(wd) / "tool_normal/data" / name) == sha(results(reference) / "tool_normal/data" / name), name


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """One uninterrupted smoke run of the tool_normal scene up to a trained model."""
    wd = copy_project(tmp_path_factory.mktemp("reference"))
    smk(wd, *CONFIG, "--", MODEL)
    yield wd
    shutil.rmtree(wd, ignore_errors=True)


def test_sigkill_during_ingest_then_rerun_equals_uninterrupted(reference, tmp_path):
    wd = clone(reference, tmp_path / "wd", drop=["results"])
    proc = start(wd, *CONFIG, "--", DATA)
    shards = wd / SHARDS

    def mid_ingest():
        # best: a shard being written right now (its temporary exists); else once two trials are
        # done and a third ingest job has started
        if shards.is_dir() and any(p.name.endswith(".tmp") for p in shards.iterdir()):
            return "temporary"
        logs = results(wd) / "logs/tool_ingest/sim-smoke"
        started = len(list(logs.glob("*.log"))) if logs.is_dir() else 0
        return "started" if len(list(shards.glob("*.parquet"))) >= 2 and started >= 3 else None

    wait_for(mid_ingest, proc, wd)
    kill_group(proc)
    n_ref = len(list((reference / SHARDS).glob("*.parquet")))
    assert len(list(shards.glob("*.parquet"))) < n_ref, "ingest had finished: nothing was interrupted"
    assert not (wd / DATA).exists()

    recover(wd, DATA)
    assert temporaries(wd) == []
    assert_same_data(wd, reference)


def test_sigkill_during_training_then_rerun_equals_uninterrupted(reference, tmp_path):
    wd = clone(reference, tmp_path / "wd", drop=[MODEL_DIR])
    proc = start(wd, *CONFIG, "--", MODEL)
    wait_for(lambda: (wd / MODEL_DIR / "last.pt").exists(), proc, wd)      # first epoch done, second running
    kill_group(proc)
    assert not (wd / MODEL).exists(), "training had finished: nothing was interrupted"

    recover(wd, MODEL)
    assert temporaries(wd) == []
    got = pd.read_parquet(wd / MODEL_DIR / "predictions.parquet")
    want = pd.read_parquet(reference / MODEL_DIR / "predictions.parquet")
    pd.testing.assert_frame_equal(got, want, check_exact=True)
    e_got, e_want = (json.loads((d / MODEL).read_text()) for d in (wd, reference))
    assert e_got["resumed_from_epoch"] >= 1 and e_want["resumed_from_epoch"] == 0   # resumed, not restarted
    skip = TIMING_FIELDS | {"resumed_from_epoch"}
    assert {k: v for k, v in e_got.items() if k not in skip} == {k: v for k, v in e_want.items() if k not in skip}
    losses = ["epoch", "train_loss", "val_loss", "val_mae_n"]
    h_got, h_want = (pd.read_csv(d / MODEL_DIR / "history.csv")[losses] for d in (wd, reference))
    pd.testing.assert_frame_equal(h_got, h_want, check_exact=True)


def test_second_snakemake_in_the_same_folder_is_refused(reference, tmp_path):
    wd = clone(reference, tmp_path / "wd", drop=[f"{SMOKE}/tool", f"{SMOKE}/tool_normal/data", f"{SMOKE}/logs"])
    first = start(wd, *CONFIG, "--", DATA)
    try:
        # the first run holds its lock and is running an ingest job
        wait_for(lambda: list((wd / ".snakemake/locks").glob("*.lock"))
                 and (results(wd) / "logs/tool_ingest").is_dir(), first, wd)
        # paused while the second one starts: on a loaded machine the first could otherwise finish
        # (and release its lock) before the second has built its DAG, and the second would succeed
        os.killpg(first.pid, signal.SIGSTOP)
        try:
            second = smk(wd, *CONFIG, "--", DATA, check=False)
        finally:
            os.killpg(first.pid, signal.SIGCONT)
        assert second.returncode != 0
        out = second.stdout + second.stderr
        assert LOCKED in out and "no other Snakemake process is trying to create the same files" in out, out
        assert first.wait(timeout=600) == 0, (wd / "background.out").read_text()[-3000:]
    finally:
        if first.poll() is None:
            kill_group(first)
    assert temporaries(wd) == []
    assert_same_data(wd, reference)


# --- the disk: full, over a size limit, read-only, forbidden -------------------------------------

CLI = [str(BIN / "tactilepipe")]


@contextlib.contextmanager
def tmpfs(path: Path, size: str):
    """A small tmpfs at ``path`` (we run as root in the test container); skips when mounting is
    not permitted (then the RLIMIT_FSIZE test still covers a write that runs out of room)."""
    path.mkdir(parents=True, exist_ok=True)
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size},mode=0755", "tmpfs", str(path)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {proc.stderr.strip()}")
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], check=False)


def cli(args: list[str], preexec=None, prefix: list[str] | None = None, env: dict | None = None
        ) -> subprocess.CompletedProcess:
    env = {**(env or ENV), "PYTHONDONTWRITEBYTECODE": "1"}
    return subprocess.run([*(prefix or []), *CLI, *args], env=env, capture_output=True, text=True,
                          preexec_fn=preexec)


def assert_one_line_error(proc: subprocess.CompletedProcess, stage: str, target: Path, problem: str) -> None:
    assert proc.returncode != 0
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"tactilepipe {stage}: error: {target}"), lines[0]
    assert problem in lines[0], lines[0]
    assert "Traceback" not in proc.stderr + proc.stdout


def test_full_disk_ingest_gives_one_line_and_keeps_the_old_shard(tmp_path, good_bag):
    probe = tmp_path / "probe.parquet"
    assert cli(["papillarray-ingest", str(good_bag), str(probe)]).returncode == 0
    size = probe.stat().st_size
    with tmpfs(tmp_path / "small", f"{max(8192, size // 2)}") as mnt:
        shard = mnt / "shard.parquet"
        shard.write_bytes(b"old shard")                       # an earlier result must survive
        proc = cli(["papillarray-ingest", str(good_bag), str(shard)])
        assert_one_line_error(proc, "papillarray-ingest", shard, "No space left on device")
        assert shard.read_bytes() == b"old shard"
        assert sorted(p.name for p in mnt.iterdir()) == ["shard.parquet"]       # no temporary


def test_full_disk_memory_mapped_dataset_is_an_error_not_sigbus(tmp_path, reference):
    """frames.npy is written through a memory map: a full disk used to kill the process with
    SIGBUS and leave the temporary behind; the blocks are now reserved first."""
    shards = sorted(str(p) for p in (reference / SHARDS).glob("*normal*.parquet"))
    with tmpfs(tmp_path / "small", "64k") as mnt:
        out = mnt / "data"
        proc = cli(["tool-dataset", "--params", str(reference / "params.yaml"), "--scale", "smoke",
                    "--kind", "normal", "--shards", *shards, "--out-dir", str(out)], env=env_of(reference))
        assert proc.returncode not in (-signal.SIGBUS, 128 + signal.SIGBUS), proc.stderr
        assert_one_line_error(proc, "tool-dataset", out / "frames.npy", "No space left on device")
        assert not out.exists() or list(out.iterdir()) == []


def test_file_size_limit_gives_one_line_and_leaves_nothing(tmp_path, good_bag):
    """RLIMIT_FSIZE (a quota-like limit that needs no mount): write() fails with EFBIG. Python
    ignores SIGXFSZ at start-up, so the child sees the error instead of being killed."""
    import resource

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))

    out = tmp_path / "out"
    shard = out / "shard.parquet"
    proc = cli(["papillarray-ingest", str(good_bag), str(shard)], preexec=limit)
    assert_one_line_error(proc, "papillarray-ingest", shard, "File too large")
    assert list(out.iterdir()) == []


def test_read_only_results_folder(tmp_path, good_bag):
    """A read-only file system (a read-only mount: root ignores permission bits, not EROFS)."""
    with tmpfs(tmp_path / "ro", "1m") as mnt:
        subprocess.run(["mount", "-o", "remount,ro", str(mnt)], check=True)
        shard = mnt / "shards" / "shard.parquet"
        proc = cli(["papillarray-ingest", str(good_bag), str(shard)])
        assert_one_line_error(proc, "papillarray-ingest", shard, "Read-only file system")
        assert list(mnt.iterdir()) == []


def test_results_folder_without_write_permission(tmp_path, good_bag):
    """A folder the user may not write to (mode 0555). Root ignores permission bits, and the
    interpreter lives under /root (0700) so the job cannot run as an unprivileged user: the child
    stays root but loses CAP_DAC_OVERRIDE (setpriv), so the mode bits apply to it."""
    if shutil.which("setpriv") is None or os.geteuid() != 0:
        pytest.skip("needs root and setpriv to drop CAP_DAC_OVERRIDE")
    folder = tmp_path / "locked"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        shard = folder / "shard.parquet"
        proc = cli(["papillarray-ingest", str(good_bag), str(shard)],
                   prefix=["setpriv", "--bounding-set=-dac_override,-dac_read_search", "--"])
        assert_one_line_error(proc, "papillarray-ingest", shard, "Permission denied")
        assert list(folder.iterdir()) == []
    finally:
        folder.chmod(0o755)


def test_stale_temporary_of_a_killed_writer_is_removed_by_the_next_write(tmp_path):
    from tactilepipe.core.atomic import write_text
    target = tmp_path / "metrics.json"
    stale = [tmp_path / ".metrics.json.k1ll3d.tmp", tmp_path / ".metrics.json.dir0.tmp"]
    stale[0].write_text("half")
    stale[1].mkdir()                                  # a ROS2 bag is written as a temporary folder
    other = tmp_path / ".other.json.x.tmp"            # another target's temporary is not touched
    other.write_text("x")
    write_text(target, "{}\n")
    assert target.read_text() == "{}\n"
    assert not any(p.exists() for p in stale) and other.exists()
