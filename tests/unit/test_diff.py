"""tactilepipe diff's judgement of two runs: paired over the same draws, by intervals otherwise,
single values as changed, and the exit status for a tolerance (end to end on a DVC project's
experiment: tests/integration/test_dvc_workflow.py)."""

from __future__ import annotations

import copy

from tactilepipe.pipeline import diff


def _model(mae: list[float]) -> dict:
    from tactilepipe.core.intervals import interval
    per = {"mae": mae, "rmse": [m * 1.5 for m in mae], "r2": [1 - m / 10 for m in mae]}
    return {"mae": mae[0], "per_split": per, "over_splits": {k: interval(v, test_train_ratio=0.2) for k, v in per.items()}}


def _tool_run(**models) -> dict:
    metrics = {"test_train_ratio": 0.2, "splits": ["trial", "trial_r1", "trial_r2"],
               "beats_baselines": {k: True for k in models}, **{k: _model(v) for k, v in models.items()}}
    provenance = {"sessions": {"raw/tool/s": "abc"},
                  "stages": {"tool-split": {"code_sha256": "1", "params": {"seed": 1}},
                             "tool-train": {"code_sha256": "2", "params": {"lr": 1e-3}}}}
    return {"metrics": metrics, "provenance": provenance}


BASE = [1.00, 1.10, 0.95, 1.05, 1.02, 0.98, 1.07, 0.93]


def _row(scene_diff, model, metric):
    return next(r for r in scene_diff.rows if r.model == model and r.metric == metric)


def test_identical_runs_are_unchanged_and_pass_any_tolerance():
    run = _tool_run(full=BASE, single=[b + 0.5 for b in BASE])
    d = diff.compare_scene("tool_normal", run, copy.deepcopy(run))
    assert d.verdict == "unchanged" and {r.verdict for r in d.rows} == {"same"}
    assert diff.failures([d], {"mae": 0.0, "r2": 0.0}) == []


def test_a_consistent_shift_over_the_same_splits_is_signal_and_scatter_is_noise():
    old = _tool_run(full=BASE, single=BASE)
    new = copy.deepcopy(old)
    new["metrics"]["full"] = _model([b + 0.2 + 0.01 * (i % 2) for i, b in enumerate(BASE)])   # worse on every split
    new["metrics"]["single"] = _model([b + (0.05 if i % 2 else -0.05) for i, b in enumerate(BASE)])
    d = diff.compare_scene("tool_normal", old, new)
    full, single = _row(d, "full", "mae"), _row(d, "single", "mae")
    assert (full.verdict, full.how) == ("signal", "paired over 8 draws") and full.low > 0
    assert (single.verdict, single.how) == ("noise", "paired over 8 draws") and single.low < 0 < single.high
    assert d.verdict.startswith("3 beyond noise: full rmse +0.3075 (signal), full mae +0.205 (signal)"), d.verdict
    fails = diff.failures([d], {"mae": 0.1})
    assert [(r.model, r.metric) for r in fails] == [("full", "mae")]
    assert diff.failures([d], {"mae": 0.3}) == []


def test_other_splits_are_judged_by_their_intervals():
    old = _tool_run(full=BASE, single=BASE)
    new = copy.deepcopy(old)
    new["provenance"]["stages"]["tool-split"]["params"]["seed"] = 2        # other draws: no pairing
    new["metrics"]["full"] = _model([b + 0.05 for b in BASE[::-1]])
    new["metrics"]["single"] = _model([b + 3.0 for b in BASE])
    d = diff.compare_scene("tool_normal", old, new)
    assert (_row(d, "full", "mae").verdict, _row(d, "full", "mae").how) == ("noise", "intervals")
    assert (_row(d, "single", "mae").verdict, _row(d, "single", "mae").how) == ("signal", "intervals")


def test_a_model_gone_and_a_verdict_flipped_are_named():
    old = _tool_run(full=BASE, no_ref=BASE)
    new = _tool_run(full=BASE)
    new["metrics"]["beats_baselines"]["full"] = False
    d = diff.compare_scene("tool_normal", old, new)
    assert _row(d, "no_ref", "mae").verdict == "removed"
    flip = _row(d, "", "beats_baselines.full")
    assert (flip.old, flip.new, flip.verdict) == (True, False, "changed")
    text = diff.markdown([d], "A", "B")
    assert "| no_ref | mae | 1.012 |  |  | removed |" in text and "**tool_normal**: 3 beyond noise" in text


def test_a_scene_without_draws_reports_any_change_and_a_missing_scene_says_so():
    old = {"metrics": {"drift_30min_n": {"loaded": 0.50}, "best_model": {"loaded": "poly3"}}, "provenance": {}}
    new = copy.deepcopy(old)
    new["metrics"]["drift_30min_n"]["loaded"] = 0.52
    d = diff.compare_scene("drift", old, new)
    assert d.verdict == "1 beyond noise: drift_30min_n.loaded +0.02 (changed)"
    assert [r.metric for r in diff.failures([d], {"loaded": 0.01})] == ["drift_30min_n.loaded"]
    assert diff.compare_scene("volume", None, new).verdict == "not in the old run"
