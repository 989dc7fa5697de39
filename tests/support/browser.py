"""Headless Chromium for the tests that render a page (Debian's `chromium`; `.ci/run` installs it,
elsewhere those tests skip without it)."""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest

# Headless in a closed network as root: no sandbox, no background or update connections.
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--hide-scrollbars", "--virtual-time-budget=10000"]
# a proxy nothing listens on: every request to another host fails at once, as on a machine offline
OFFLINE = ["--proxy-server=http://127.0.0.1:9", "--proxy-bypass-list=<-loopback>"]


def chromium() -> str:
    path = shutil.which("chromium") or shutil.which("chromium-browser")
    if path is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is missing: .ci/run installs it for the rendering tests")
        pytest.skip("chromium is not installed (apt-get install chromium): the rendering tests need it")
    return path


def chromium_run(page: Path, *args: str) -> str:
    """Chromium's stdout for ``page`` (a file) with ``args`` (e.g. --dump-dom)."""
    with tempfile.TemporaryDirectory() as profile:
        return subprocess.run([chromium(), *CHROMIUM_FLAGS, f"--user-data-dir={profile}", *args,
                               page.resolve().as_uri()], capture_output=True, text=True, timeout=240,
                              check=True).stdout
