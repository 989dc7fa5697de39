"""tactilepipe diff's judgement of two runs: paired over the same draws, by intervals otherwise,
single values as changed, and the exit status for a tolerance (end to end on a DVC project's
experiment: tests/integration/test_dvc_workflow.py)."""

from __future__ import annotations

import copy
import sys

import pytest

from tactilepipe.pipeline import diff


def _model(mae: list[float]) -> dict:
    """A model as scores.json holds it: the means over the splits on top, the first split's under its name."""
    from tactilepipe.core.intervals import interval
    per = {"mae": mae, "rmse": [m * 1.5 for m in mae], "r2": [1 - m / 10 for m in mae]}
    over = {k: interval(v, test_train_ratio=0.2) for k, v in per.items()}
    return {**{k: over[k]["mean"] for k in per}, "first_split": {"split": "trial", **{k: v[0] for k, v in per.items()}},
            "per_split": per, "over_splits": over}


def _old_layout(metrics: dict) -> dict:
    """The tool scores as metrics.json held them before scores.json: each model's top-level scores
    its first split's, the scene's first split named by ``split`` beside ``test_pairs``."""
    m = copy.deepcopy(metrics)
    first = m.pop("first_split")
    m["split"], m["test_pairs"] = first["split"], first["test_pairs"]
    for model in m.values():
        if isinstance(model, dict) and "per_split" in model:
            model.update({k: v for k, v in model.pop("first_split").items() if k != "split"})
    return m


def _tool_run(**models) -> dict:
    metrics = {"test_train_ratio": 0.2, "splits": ["trial", "trial_r1", "trial_r2"],
               "first_split": {"split": "trial", "test_pairs": 100},
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


def test_a_run_in_the_layout_before_scores_json_reads_as_todays_and_compares_unchanged():
    """A committed run of an earlier revision (top-level scores its first split's) against the same
    numbers in today's layout: no score or first-split value is added, removed or changed."""
    new = _tool_run(full=BASE, single=[b + 0.5 for b in BASE])
    old = {**new, "metrics": _old_layout(new["metrics"])}
    assert old["metrics"]["full"]["mae"] == BASE[0] != new["metrics"]["full"]["mae"]
    assert diff.current_layout("tool_normal", old["metrics"]) == new["metrics"]
    d = diff.compare_scene("tool_normal", old, new)
    assert d.verdict == "unchanged" and {r.verdict for r in d.rows} == {"same"}, [r for r in d.rows if r.verdict != "same"]
    assert _row(d, "", "full.first_split.mae").new == BASE[0]
    assert _row(d, "full", "mae").new == pytest.approx(sum(BASE) / len(BASE))
    assert not [r for r in d.rows if r.how == "single value" and r.metric in ("full.mae", "full.rmse", "full.r2")]
    # a first split that moved, its mean not: a changed single value, named as the first split's
    moved = copy.deepcopy(new)
    moved["metrics"]["full"]["first_split"]["mae"] += 0.1
    assert _row(diff.compare_scene("tool_normal", old, moved), "", "full.first_split.mae").verdict == "changed"


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


def test_values_that_differ_in_their_last_digits_are_rounding_not_changes():
    # measured on the committed default build: an AVX2 machine's drift fits against an AVX-512 one's
    old = {"metrics": {"recalibration_interval_min": {"loaded": 2.766123456789},
                       "fits": {"loo_r2": 0.9922, "model": "exp"}}, "provenance": {}}
    new = copy.deepcopy(old)
    new["metrics"]["recalibration_interval_min"]["loaded"] += 2.3e-12
    d = diff.compare_scene("drift", old, new)
    assert d.verdict == "unchanged but for rounding: 1 values differ in their last digits only (at most 8e-13 relative)"
    assert diff.failures([d], {"loaded": 0.0}) == []          # not worse by any tolerance a user can set
    # beyond 1e-9 of the value it is a change, reported as before
    new["metrics"]["fits"]["loo_r2"] = 0.9922 * (1 + 2e-9)
    d = diff.compare_scene("drift", old, new)
    assert d.verdict.startswith("1 beyond noise: fits.loo_r2") and d.verdict.endswith(
        "(changed); 1 values differ in their last digits only (at most 8e-13 relative)"), d.verdict
    assert {r.metric: r.verdict for r in d.rows if r.verdict != "same"} == {
        "fits.loo_r2": "changed", "recalibration_interval_min.loaded": "rounding"}


def test_a_score_whose_draws_differ_in_rounding_only_is_not_judged_as_noise():
    old = _tool_run(full=BASE)
    new = _tool_run(full=[v * (1 + 1e-14) for v in BASE])
    d = diff.compare_scene("tool_normal", old, new)
    assert _row(d, "full", "mae").verdict == "rounding" and d.verdict.startswith("unchanged but for rounding"), d.verdict


# --- non-finite scores are regressions, never noise ---------------------------------------------------

def test_a_score_that_became_nan_or_null_fails_any_tolerance_and_is_not_noise():
    old = _tool_run(full=BASE, single=BASE)
    for bad in (float("nan"), None):
        new = copy.deepcopy(old)
        new["metrics"]["full"]["over_splits"]["mae"]["mean"] = bad
        new["metrics"]["full"]["per_split"]["mae"] = [bad] * len(BASE)
        new["metrics"]["single"]["per_split"]["mae"][3] = bad      # one draw: the interval leaves it out
        d = diff.compare_scene("tool_normal", old, new)
        full, single = _row(d, "full", "mae"), _row(d, "single", "mae")
        assert (full.verdict, full.nonfinite) == ("non-finite", True), bad
        assert (single.verdict, single.nonfinite) == ("non-finite", True), bad
        assert d.verdict.startswith("2 beyond noise: full mae non-finite"), d.verdict
        assert {(r.model, r.metric) for r in diff.failures([d], {"mae": 1e9})} == {("full", "mae"), ("single", "mae")}


def test_a_single_value_that_became_null_or_nan_fails_its_tolerance():
    old = {"metrics": {"drift_30min_n": {"loaded": 0.50, "unloaded": 0.1}}, "provenance": {}}
    new = copy.deepcopy(old)
    new["metrics"]["drift_30min_n"] = {"loaded": None, "unloaded": float("nan")}
    d = diff.compare_scene("drift", old, new)
    assert {r.metric for r in diff.failures([d], {"loaded": 1e9, "unloaded": 1e9})} == \
        {"drift_30min_n.loaded", "drift_30min_n.unloaded"}


# --- pairing over the draws two runs share ------------------------------------------------------------

def _repeats(run: dict, k: int) -> dict:
    """``run`` as a build with ``k`` repeats of its split would give it: the first k draws."""
    from tactilepipe.core.intervals import interval
    run = copy.deepcopy(run)
    m = run["metrics"]
    m["splits"] = ["trial"] + [f"trial_r{i}" for i in range(1, k)]
    m["repeats"] = k
    for name, model in list(m.items()):
        if isinstance(model, dict) and "per_split" in model:
            model["per_split"] = {s: v[:k] for s, v in model["per_split"].items()}
            model["over_splits"] = {s: interval(v, test_train_ratio=0.2) for s, v in model["per_split"].items()}
    return run


def test_a_6_repeat_and_an_8_repeat_build_are_paired_over_their_6_shared_draws():
    eight = _tool_run(full=BASE, single=BASE)
    eight["metrics"]["splits"] = ["trial"] + [f"trial_r{i}" for i in range(1, 8)]
    six = _repeats(eight, 6)
    # the same models on the shared draws: the extra two draws move the mean, not the pairing
    d = diff.compare_scene("tool_normal", six, eight)
    row = _row(d, "full", "mae")
    assert (row.verdict, row.how) == ("noise", "paired over 6 shared draws"), (row.verdict, row.how)
    assert row.low == row.high == 0.0
    # worse by 0.08 on every draw: a paired signal, which the two intervals (overlapping) would miss
    worse = copy.deepcopy(eight)
    worse["metrics"]["full"] = _model([b + 0.08 + 0.01 * (i % 2) for i, b in enumerate(BASE)])
    d = diff.compare_scene("tool_normal", six, worse)
    row = _row(d, "full", "mae")
    assert (row.verdict, row.how) == ("signal", "paired over 6 shared draws") and row.low > 0
    o, n = six["metrics"]["full"]["over_splits"]["mae"], worse["metrics"]["full"]["over_splits"]["mae"]
    assert n["low"] < o["high"], "the intervals overlap: only the pairing sees the change"
    # the draws named alike, not by position: a build whose draws are other splits is not paired
    other = copy.deepcopy(worse)
    other["metrics"]["splits"] = [f"trial_r{i}" for i in range(8, 16)]
    assert _row(diff.compare_scene("tool_normal", six, other), "full", "mae").how == "intervals"


# --- through the command line -------------------------------------------------------------------------

def _write_run(root, run: dict, old_layout: bool = False) -> None:
    """A tool run's files as the report writes them: scores.json and its headline, metrics.json; or
    (``old_layout``) as an earlier revision did, everything in metrics.json."""
    import json
    scene = root / "results" / "tool_normal"
    scene.mkdir(parents=True, exist_ok=True)
    # json writes NaN as NaN, as the pipeline's metrics would
    if old_layout:
        (scene / "scores.json").unlink(missing_ok=True)
        (scene / "metrics.json").write_text(json.dumps(_old_layout(run["metrics"])))
    else:
        (scene / "scores.json").write_text(json.dumps(run["metrics"]))
        (scene / "metrics.json").write_text(json.dumps({"full": {"mae": run["metrics"]["full"]["mae"]}}))
    (scene / "provenance.json").write_text(json.dumps(run["provenance"]))


@pytest.fixture(scope="module")
def committed(tmp_path_factory):
    """A git repository (with DVC) whose HEAD holds one tool run's metrics, in the layout before
    scores.json: the diffs against it read an earlier commit's results."""
    import subprocess
    root = tmp_path_factory.mktemp("diffrepo")
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-c", "commit.gpgsign=false"]
    subprocess.run(["git", "init", "-q", str(root)], check=True)
    subprocess.run([sys.executable, "-m", "dvc", "init", "-q"], cwd=root, check=True)
    _write_run(root, _tool_run(full=BASE, single=BASE), old_layout=True)
    subprocess.run(git + ["add", "-A"], cwd=root, check=True)
    subprocess.run(git + ["commit", "-q", "-m", "run"], cwd=root, check=True)
    return root


@pytest.mark.parametrize("bad", ["nan", "null"])
def test_the_ci_gate_fails_a_run_whose_mae_became_nan_or_null(committed, bad, capsys):
    from tactilepipe.cli.main import main
    new = _tool_run(full=BASE, single=BASE)
    new["metrics"]["full"]["over_splits"]["mae"]["mean"] = float("nan") if bad == "nan" else None
    new["metrics"]["full"]["per_split"]["mae"] = [float("nan") if bad == "nan" else None] * len(BASE)
    _write_run(committed, new)
    status = main(["diff", "--repo", str(committed), "--scenes", "tool_normal", "--fail-on", "mae=0.05"])
    out, err = capsys.readouterr()
    assert status == 1, out + err
    assert "within noise" not in out and "full mae non-finite" in out
    assert "tool_normal: full mae is not a number in the new run" in err


def test_the_same_run_committed_in_the_old_layout_and_written_in_todays_is_unchanged(committed, capsys):
    from tactilepipe.cli.main import main
    _write_run(committed, _tool_run(full=BASE, single=BASE))
    status = main(["diff", "--repo", str(committed), "--scenes", "tool_normal", "--fail-on", "mae=0"])
    out, err = capsys.readouterr()
    assert status == 0 and "**tool_normal**: unchanged" in out, out + err


@pytest.mark.parametrize("tolerance", ["nan", "inf", "-0.1"])
def test_a_tolerance_that_is_not_a_finite_number_is_refused(committed, tolerance, capsys):
    from tactilepipe.cli.main import main
    status = main(["diff", "--repo", str(committed), "--scenes", "tool_normal", "--fail-on", f"mae={tolerance}"])
    assert status == 2
    assert f"--fail-on 'mae={tolerance}': the tolerance must be a finite number >= 0" in capsys.readouterr().err


def test_draws_whose_baselines_score_alike_are_paired_though_earlier_code_changed():
    eight = _tool_run(full=BASE)
    eight["metrics"]["splits"] = ["trial"] + [f"trial_r{i}" for i in range(1, 8)]
    eight["metrics"]["test_pairs_per_split"] = [100 + i for i in range(8)]
    eight["metrics"]["baselines"] = {"mean_predictor": _model([5.0 + 0.1 * i for i in range(8)])}
    six = _repeats(eight, 6)
    six["metrics"]["test_pairs_per_split"] = eight["metrics"]["test_pairs_per_split"][:6]
    new = copy.deepcopy(eight)
    new["provenance"]["stages"]["tool-split"]["code_sha256"] = "refactored"      # provenance cannot tell
    new["metrics"]["full"] = _model([b + 0.08 + 0.01 * (i % 2) for i, b in enumerate(BASE)])
    row = _row(diff.compare_scene("tool_normal", six, new), "full", "mae")
    assert (row.verdict, row.how) == ("signal", "paired over 6 shared draws")
    assert abs(row.change - 0.085) < 1e-9                  # the mean change over the shared draws
    # a baseline scoring otherwise on a draw: that draw is another split, and is left out
    new["metrics"]["baselines"]["mean_predictor"]["per_split"]["mae"][2] += 0.5
    assert _row(diff.compare_scene("tool_normal", six, new), "full", "mae").how == "paired over 5 shared draws"
    new["metrics"]["test_pairs_per_split"] = [7] * 8                              # other test sets
    assert _row(diff.compare_scene("tool_normal", six, new), "full", "mae").how == "intervals"


def test_an_old_revisions_two_way_orderings_are_read_against_the_four_way_ones():
    """A revision from before the equivalence margin judged orderings 'holds' or 'undecided' with no
    margin or power line; the diff reads it against today's rows, naming what changed."""
    from tactilepipe.tool.report.verdicts import margin_n, paper_orderings
    full, no_gam = BASE, [b + (0.01 if i % 2 else -0.005) for i, b in enumerate(BASE)]
    scores = {"full": {"mae": full}, "no_gam": {"mae": no_gam}}
    old, new = _tool_run(full=full, no_gam=no_gam), _tool_run(full=full, no_gam=no_gam)
    new["metrics"]["paper_orderings"] = paper_orderings("tool_normal", scores, 0.2, margin_n(scores, 0.1))
    old["metrics"]["paper_orderings"] = [{k: new["metrics"]["paper_orderings"][0][k] for k in
                                          ("claim", "better", "worse", "mae_difference", "low", "high")}
                                         | {"verdict": "undecided"}]
    d = diff.compare_scene("tool_normal", old, new)
    assert new["metrics"]["paper_orderings"][0]["verdict"] == "equivalent"
    flip = _row(d, "", "paper_orderings.0.verdict")
    assert (flip.old, flip.new, flip.verdict) == ("undecided", "equivalent", "changed")
    assert _row(d, "", "paper_orderings.0.margin").verdict == "added"
    assert _row(d, "", "paper_orderings.0.power").new == ""
    assert d.verdict == "scores unchanged; 7 other values changed", d.verdict
    assert "| paper_orderings.0.verdict | undecided | equivalent | " in diff.markdown([d], "A", "B", show_same=True)


def test_runs_recorded_before_sessions_took_dvcs_hash_are_still_read_and_paired_among_themselves():
    """provenance.json of older revisions names a session by a sha256 of its own; newer ones by
    DVC's md5 (a folder's ``.dir`` hash). Two old runs, or two new ones, of the same data pair;
    an old and a new one cannot show the data is the same, so they are judged by intervals."""
    old_layout, dvc_layout = "46ff453c25b546eac85e1814446402efcf414fc604879df81ebd283ee07dd5ce", \
        "30bac1eaacb5412a18f6d134c4fd829c.dir"
    runs = {}
    for name, session in (("old", old_layout), ("new", dvc_layout)):
        before = _tool_run(full=BASE)
        before["provenance"]["sessions"] = {"raw/tool/s": session}
        after = copy.deepcopy(before)
        after["metrics"]["full"] = _model([b + 0.08 + 0.01 * (i % 2) for i, b in enumerate(BASE)])
        runs[name] = before, after
    for name in ("old", "new"):
        row = _row(diff.compare_scene("tool_normal", *runs[name]), "full", "mae")
        assert (row.verdict, row.how) == ("signal", "paired over 8 draws"), name
    mixed = _row(diff.compare_scene("tool_normal", runs["old"][0], runs["new"][1]), "full", "mae")
    assert mixed.how == "intervals"


def test_a_stage_that_declares_its_rule_in_a_scene_does_not_change_its_draws():
    """Only the stages its study lists for the scene, and its simulator, fix the draws: a summary or
    figure stage added to the scene (recorded in provenance.json) leaves the pairing alone."""
    base = {"sessions": {"raw/volume/s1": "abc"},
            "stages": {"volume-simulate": {"params": {"seed": 1}}, "volume-split": {"params": {"folds": 5}},
                       "volume-report": {"params": {"x": 1}}}}
    with_summary = {**base, "stages": {**base["stages"], "volume-summary": {"code_sha256": "f00"}}}
    other_split = {**base, "stages": {**base["stages"], "volume-split": {"params": {"folds": 4}}}}
    assert diff.draws_identity(with_summary, "volume") == diff.draws_identity(base, "volume")
    assert diff.draws_identity(other_split, "volume") != diff.draws_identity(base, "volume")
