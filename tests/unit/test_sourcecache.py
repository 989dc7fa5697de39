"""Values kept between runs for the exact package source they came from (core.sourcecache):
the stage code closures and the models' forward FLOPs."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from tactilepipe.core import sourcecache
from tactilepipe.pipeline import codedeps
from tactilepipe.tool import estimate


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    folder = tmp_path / "tactilepipe"
    monkeypatch.setattr(sourcecache, "CACHE_DIR", folder)
    _forget()
    yield folder
    _forget()                                        # later tests read the real cache again


def _forget():
    codedeps._stored_closures.cache_clear()
    estimate.forward_flops.cache_clear()


def test_closures_are_read_back_only_for_the_same_source(cache_dir, monkeypatch):
    computed = codedeps.stage_modules("drift-report")
    assert "tactilepipe.drift.analyse" in computed
    stored = json.loads((cache_dir / "stage-modules.json").read_text())
    assert stored["digest"] == sourcecache.source_digest()
    assert stored["entries"]["drift-report"] == sorted(computed)

    # what the file says is what a new process gets, as long as the source digest matches
    stored["entries"]["drift-report"].append("tactilepipe.marker")
    (cache_dir / "stage-modules.json").write_text(json.dumps(stored))
    _forget()
    assert codedeps.stage_modules("drift-report") == computed | {"tactilepipe.marker"}

    # any other source (one edited file changes the digest): recomputed and stored again
    monkeypatch.setattr(sourcecache, "source_digest", lambda: "another source")
    _forget()
    assert codedeps.stage_modules("drift-report") == computed
    assert json.loads((cache_dir / "stage-modules.json").read_text())["digest"] == "another source"


def test_an_unreadable_or_unwritable_cache_only_costs_time(cache_dir, monkeypatch, tmp_path):
    cache_dir.mkdir()
    (cache_dir / "stage-modules.json").write_text("{not json")
    expected = codedeps.stage_modules("drift-report")
    (tmp_path / "file").write_text("a file where the cache folder should be")
    monkeypatch.setattr(sourcecache, "CACHE_DIR", tmp_path / "file")
    _forget()
    assert codedeps.stage_modules("drift-report") == expected
    assert estimate.forward_flops("full", 18, 8, "sigmoid", 8) > 0


def test_forward_flops_are_counted_once_per_model_and_source(cache_dir, monkeypatch):
    args = ("full", 18, 16, "sigmoid", 8)
    counted = estimate._count_forward_flops(*args)
    assert estimate.forward_flops(*args) == counted
    entries = json.loads((cache_dir / "forward-flops.json").read_text())["entries"]
    assert list(entries.values()) == [counted]
    assert estimate.forward_flops("single", 18, 16, "sigmoid", 8) < counted       # one finger's encoder less
    assert len(json.loads((cache_dir / "forward-flops.json").read_text())["entries"]) == 2

    # a new process reads the count back without importing torch
    code = ("import sys; from tactilepipe.tool.estimate import forward_flops; "
            f"print(forward_flops{args!r}); assert 'torch' not in sys.modules, 'torch imported'")
    out = subprocess.run([sys.executable, "-c", code], env={**os.environ, "XDG_CACHE_HOME": str(cache_dir.parent)},
                         capture_output=True, text=True, check=True).stdout
    assert float(out) == counted

    # another source: counted again, and only this source's counts are kept
    monkeypatch.setattr(sourcecache, "source_digest", lambda: "another source")
    _forget()
    assert estimate.forward_flops(*args) == counted
    stored = json.loads((cache_dir / "forward-flops.json").read_text())
    assert stored["digest"] == "another source" and len(stored["entries"]) == 1
