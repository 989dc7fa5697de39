"""The stage code closures are kept in a cache file that is valid only for the source it came from."""

from __future__ import annotations

import json

import pytest

from tactilepipe.pipeline import codedeps


@pytest.fixture(autouse=True)
def _forget_afterwards():
    yield
    codedeps._stored_closures.cache_clear()          # later tests read the real cache again


def _fresh(monkeypatch, cache, digest=None):
    monkeypatch.setattr(codedeps, "_CLOSURE_CACHE", cache)
    if digest is not None:
        monkeypatch.setattr(codedeps, "_source_digest", lambda: digest)
    codedeps._stored_closures.cache_clear()


def test_closures_are_read_back_only_for_the_same_source(tmp_path, monkeypatch):
    cache = tmp_path / "stage-modules.json"
    _fresh(monkeypatch, cache)
    computed = codedeps.stage_modules("cmd_report_drift")
    assert "tactilepipe.drift.analyse" in computed
    stored = json.loads(cache.read_text())
    assert stored["digest"] == codedeps._source_digest()
    assert stored["stages"]["cmd_report_drift"] == sorted(computed)

    # what the file says is what a new process gets, as long as the source digest matches
    stored["stages"]["cmd_report_drift"].append("tactilepipe.marker")
    cache.write_text(json.dumps(stored))
    _fresh(monkeypatch, cache)
    assert codedeps.stage_modules("cmd_report_drift") == computed | {"tactilepipe.marker"}

    # any other source (one edited file changes the digest): recomputed and stored again
    _fresh(monkeypatch, cache, digest="another source")
    assert codedeps.stage_modules("cmd_report_drift") == computed
    assert json.loads(cache.read_text())["digest"] == "another source"


def test_an_unreadable_or_unwritable_cache_only_costs_time(tmp_path, monkeypatch):
    (tmp_path / "stage-modules.json").write_text("{not json")
    _fresh(monkeypatch, tmp_path / "stage-modules.json")
    expected = codedeps.stage_modules("cmd_report_drift")
    blocked = tmp_path / "file" / "stage-modules.json"
    (tmp_path / "file").write_text("a file where the cache folder should be")
    _fresh(monkeypatch, blocked)
    assert codedeps.stage_modules("cmd_report_drift") == expected
