"""DVC's metrics as a file per row (core/metric_rows.py)."""

from __future__ import annotations

import json

from tactilepipe.core.metric_rows import metric_files, write_metric_rows


def test_rows_are_files_with_their_own_keys_and_a_dropped_row_is_removed(tmp_path):
    write_metric_rows(tmp_path, {"full": {"mae": 1.1, "r2": 0.9}, "no_ref": {"mae": 1.9, "r2": 0.7}})
    assert sorted(p.name for p in (tmp_path / "metrics").iterdir()) == ["full.json", "no_ref.json"]
    assert json.loads((tmp_path / "metrics" / "no_ref.json").read_text()) == {"mae": 1.9, "r2": 0.7}
    # a later build without no_ref: its row would still be shown by DVC (the folder is declared)
    (tmp_path / "metrics" / "notes.txt").write_text("")             # not a row: left alone
    write_metric_rows(tmp_path, {"full": {"mae": 1.2, "r2": 0.9}})
    assert sorted(p.name for p in (tmp_path / "metrics").iterdir()) == ["full.json", "notes.txt"]
    assert json.loads((tmp_path / "metrics" / "full.json").read_text()) == {"mae": 1.2, "r2": 0.9}


def test_the_files_of_rows_are_named_by_the_row():
    assert metric_files(["fy", "baseline"]) == ["metrics/fy.json", "metrics/baseline.json"]
