"""Rules generated from the stages' declarations (pipeline/stage_rules.py)."""

from __future__ import annotations

import pytest

from tactilepipe.core.errors import TactilepipeError
from tactilepipe.pipeline import stage_rules
from tactilepipe.pipeline.scenes import scene_targets
from tactilepipe.pipeline.sessions import SessionSheet


def test_the_declared_rules_are_read_from_the_source():
    rules = {r.stage: r for r in stage_rules.stage_rules()}
    split = rules["volume-split"]
    assert (split.name, split.scene, split.local) == ("volume_split", "volume", True)
    assert split.inputs == (("dataset", "volume/dataset.parquet"),)
    assert split.file_args("results/my build") == ("--dataset 'results/my build/volume/dataset.parquet' "
                                                   "--out 'results/my build/volume/folds.json'")
    assert split.named_outputs("results/smoke") == {"out": "results/smoke/volume/folds.json"}
    assert rules["volume-gridsearch"].local is False
    # a stage with several outputs takes each as its own argument (no folder to write into)
    assert dict(rules["volume-baseline"].outputs)["fold-scores"] == "volume/baseline/folds.csv"
    assert [r.stage for r in stage_rules.stage_rules(["drift"])] == []


def test_a_declared_output_is_a_target_of_its_scene(smoke_params):
    declared = stage_rules.declared_outputs(["volume"], "results/smoke")
    assert set(declared) == {"results/smoke/volume/folds.json", "results/smoke/volume/mlp/grid.csv"} | \
        {f"results/smoke/volume/baseline/{f}" for f in ("predictions.parquet", "folds.csv", "mu_curve.csv", "mu.json")}
    assert stage_rules.declared_outputs(["drift", "tool_normal"], "results/smoke") == []
    # the report's outputs are the hand-written rules' targets, which the declared ones join
    hand = scene_targets(["volume"], "results/smoke", smoke_params, SessionSheet(smoke_params))
    assert "results/smoke/volume/metrics/baseline.json" in hand and not set(declared) & set(hand)


@pytest.mark.parametrize("decl, problem", [
    ({"scene": "volume", "inputs": {"table": "volume/dataset.parquet"}, "outputs": {"out": "volume/f.json"}},
     "inputs key 'table' is not one of the stage's arguments"),
    ({"scene": "volume", "inputs": {"dataset": "/tmp/dataset.parquet"}, "outputs": {"out": "volume/f.json"}},
     "must be a fixed path under the build's folder"),
    ({"scene": "volume", "inputs": {"dataset": "volume/{x}.parquet"}, "outputs": {"out": "volume/f.json"}},
     "must be a fixed path"),
    ({"scene": "volume", "inputs": {"dataset": "volume/../../../etc/passwd"}, "outputs": {"out": "volume/f.json"}},
     "must be a fixed path"),
    ({"scene": "volume", "inputs": {"dataset": "volume/dataset.parquet"}, "outputs": {"out": "params/volume-split.json"}},
     "outside its params and logs folders"),
    ({"scene": "lab", "inputs": {}, "outputs": {"out": "volume/f.json"}}, "scene 'lab' is none of"),
    ({"scene": ["volume"], "inputs": {}, "outputs": {"out": "volume/f.json"}}, "is none of"),
    ({"scene": "volume", "inputs": {}, "outputs": {}}, "at least one output"),
    ({"scene": "volume", "inputs": {}, "outputs": {"out": "f.json"}, "threads": 2}, "must be a dict of scene"),
    ({"scene": "volume", "inputs": {}, "outputs": {"out": "volume/f.png"}, "report": {"figure": "Lifts"}},
     "report must map some of its outputs' arguments to the label"),
    ({"scene": "volume", "inputs": {}, "outputs": {"out": "volume/f.png"}, "report": {"out": " "}},
     "report must map"),
])
def test_a_wrong_declaration_is_named_with_its_stage(decl, problem):
    with pytest.raises(TactilepipeError, match=f"stage volume-split: its rule= declaration.*{problem}"):
        stage_rules._checked("volume-split", decl)


def test_an_argument_named_like_the_rules_own_inputs_is_refused(monkeypatch):
    monkeypatch.setattr(stage_rules.codedeps, "stage_flags", lambda stage: {"--code", "--out"})
    with pytest.raises(TactilepipeError, match="argument '--code' is given twice, or its name is one the rule keeps"):
        stage_rules._checked("volume-split", {"scene": "volume", "inputs": {"code": "volume/a.json"},
                                              "outputs": {"out": "volume/f.json"}})


def test_a_new_stage_module_with_a_mistake_is_one_error_naming_it(tmp_path):
    """The command line finds its study modules: one that cannot be imported (a new stage's, with a
    mistake) stops every command with one line naming its file, not a traceback."""
    import os
    import shutil
    import subprocess
    import sys
    from pathlib import Path
    src = tmp_path / "src"
    shutil.copytree(Path(stage_rules.__file__).parents[1], src / "tactilepipe", ignore=shutil.ignore_patterns("__pycache__"))
    (src / "tactilepipe/cli/volume_summary.py").write_text("from tactilepipe.volume import no_such_module\n")
    proc = subprocess.run([sys.executable, "-m", "tactilepipe", "volume-split", "--help"], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(src)}, cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "cli/volume_summary.py: cannot be imported (ImportError" in proc.stderr, proc.stderr


def test_every_report_item_has_its_caption_file_and_a_readable_label(smoke_params):
    """What the rules mark for the report (workflow/rules/*.smk `reported`): each item's caption
    is a file of workflow/report/, every caption file is used, and each item has a label."""
    from pathlib import Path
    from tactilepipe.pipeline import scenes
    from tactilepipe.tool import contract as tool
    res = "results/smoke"
    tool_files = [f"{res}/{{scene}}/qc.md"] + scenes.metric_outputs(f"{res}/{{scene}}", "tool", smoke_params) + \
        [f"{res}/{{scene}}/figures/{f}.png" for f in tool.DATA_FIGURES + tool.model_figures(smoke_params)] + \
        [f"{res}/{{scene}}/tables/{t}.md" for t in tool.model_tables(smoke_params)]
    items = scenes.report_items(scenes.report_outputs("volume", res, smoke_params), "volume", smoke_params) + \
        scenes.report_items(scenes.report_outputs("drift", res, smoke_params), "drift", smoke_params) + \
        scenes.report_items(tool_files, "tool", smoke_params) + \
        [item for rule in stage_rules.stage_rules() for item in rule.report_items(res).values()]
    report_dir = Path(__file__).resolve().parents[2] / "workflow" / "report"
    captions = {caption for _, caption, _, _ in items if caption}
    assert captions == {f"../report/{p.relative_to(report_dir)}" for p in report_dir.glob("*/*.rst")}
    for f, caption, kind, labels in items:
        assert (caption is None) == (labels is None), f
        assert labels is None or (labels["result"] and "_" not in labels["result"]), (f, labels)


def test_a_report_item_of_a_declared_stage_has_its_label_and_its_studys_caption_file():
    rule = stage_rules._checked("volume-split", {"scene": "volume", "inputs": {"dataset": "volume/dataset.parquet"},
                                                 "outputs": {"out": "volume/figures/folds.png"},
                                                 "report": {"out": "Lifts per fold"}})
    assert rule.report_items("results/smoke") == {"out": ("results/smoke/volume/figures/folds.png",
                                                          "../report/volume/folds.rst", "figures",
                                                          {"result": "Lifts per fold"})}


def test_every_rule_written_by_hand_says_why_beside_it():
    """A rule in workflow/rules/ is a stage the declaration cannot describe yet, or a target list:
    the comment right above it says which ("# By hand: <what the declaration cannot say>")."""
    import re
    from pathlib import Path
    rules_dir = Path(__file__).resolve().parents[2] / "workflow" / "rules"
    unexplained, found = [], 0
    for path in sorted(rules_dir.glob("*.smk")):
        text = path.read_text()
        for m in re.finditer(r"^rule (\w+):$", text, flags=re.M):
            found += 1
            above = text[:m.start()].rstrip("\n").splitlines()
            block = []
            while above and above[-1].startswith("#"):
                block.insert(0, above.pop())
            first = block[0] if block else ""
            if not (first.startswith("# By hand: ") and len(" ".join(block)) > 40 or first == "# A target list, not a stage."):
                unexplained.append(f"{path.name}: rule {m.group(1)}")
    assert found >= 1 and not unexplained, unexplained
