"""The S3 remote path: `dvc push` / `git clone` + `dvc pull` through the dvc-s3 plugin against a
real S3-compatible server (moto's) started by the test on loopback. No traffic leaves 127.0.0.1."""

from __future__ import annotations

import os
import socket
import subprocess

import pytest

from support.project import BIN, ENV, REPO, run

pytestmark = pytest.mark.integration

BUCKET = "tactilepipe-test"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def s3_server():
    from moto.server import ThreadedMotoServer
    port = free_port()
    server = ThreadedMotoServer(ip_address="127.0.0.1", port=port, verbose=False)
    server.start()
    endpoint = f"http://127.0.0.1:{port}"
    creds = {"AWS_ACCESS_KEY_ID": "testing", "AWS_SECRET_ACCESS_KEY": "testing", "AWS_DEFAULT_REGION": "us-east-1"}
    import boto3
    s3 = boto3.client("s3", endpoint_url=endpoint, region_name="us-east-1",
                      aws_access_key_id="testing", aws_secret_access_key="testing")
    s3.create_bucket(Bucket=BUCKET)
    try:
        yield {"endpoint": endpoint, "client": s3, "env": creds}
    finally:
        server.stop()


def dvc(wd, env, *args):
    proc = subprocess.run([str(BIN / "dvc"), *args], cwd=wd, env=env, capture_output=True, text=True)
    assert proc.returncode == 0, f"dvc {' '.join(args)}:\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}"
    return proc.stdout


def test_push_and_pull_through_an_s3_remote(tmp_path, s3_server):
    env = {**ENV, **s3_server["env"], "NO_PROXY": "127.0.0.1,localhost", "no_proxy": "127.0.0.1,localhost"}
    for var in ("HTTP_PROXY", "HTTPS_PROXY", "http_proxy", "https_proxy", "AWS_PROFILE"):
        env.pop(var, None)
    wd = tmp_path / "project"
    wd.mkdir()
    run(["git", "init", "-q"], wd)
    run(["git", "config", "user.email", "test@example.com"], wd)
    run(["git", "config", "user.name", "test"], wd)
    dvc(wd, env, "init", "-q")
    (wd / ".dvc/config").write_text((REPO / ".dvc/config").read_text())
    # a recorded session: binary bags (with every byte value) and its labels
    session = wd / "raw/volume/s1"
    session.mkdir(parents=True)
    payloads = {f"v{v:03d}_main_l00.bag": bytes(range(256)) * 64 + os.urandom(4096) for v in (0, 150, 300)}
    for name, data in payloads.items():
        (session / name).write_bytes(data)
    (session / "lifts.csv").write_text("bag,volume_ml,set\n" + "".join(f"{n},{n[1:4].lstrip('0') or 0},main\n"
                                                                    for n in payloads))
    dvc(wd, env, "add", "raw/volume/s1")
    # the S3 set-up of docs/dvc.md; the endpoint is only needed for an S3-compatible server
    dvc(wd, env, "remote", "add", "-d", "s3", f"s3://{BUCKET}/dvc")
    dvc(wd, env, "remote", "modify", "s3", "endpointurl", s3_server["endpoint"])
    run(["git", "add", "."], wd)
    run(["git", "commit", "-q", "-m", "session s1"], wd)
    dvc(wd, env, "push")
    keys = [o["Key"] for o in s3_server["client"].list_objects_v2(Bucket=BUCKET).get("Contents", [])]
    assert len(keys) == len(payloads) + 2, keys          # 3 bags + lifts.csv + the directory listing
    assert all(k.startswith("dvc/files/md5/") for k in keys), keys

    clone = tmp_path / "clone"
    run(["git", "clone", "-q", str(wd), str(clone)], tmp_path)
    assert not (clone / "raw/volume/s1").exists()
    assert "s3" in dvc(clone, env, "remote", "list")
    dvc(clone, env, "pull")
    for name, data in payloads.items():
        assert (clone / "raw/volume/s1" / name).read_bytes() == data
    assert (clone / "raw/volume/s1/lifts.csv").read_text() == (session / "lifts.csv").read_text()
    assert "up to date" in dvc(clone, env, "status").lower()
