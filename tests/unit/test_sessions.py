"""The session sheet (pipeline/sessions.py): what a build reads, planned or found on the disk."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tactilepipe.core.errors import InputError
from tactilepipe.pipeline.sessions import SessionSheet
from tactilepipe.tool import contract as tool_contract
from tactilepipe.tool.formats.native_layout import TrialMeta
from tactilepipe.tool.sim import session_plan as tool_plan
from tactilepipe.volume.simulate import session_plan as volume_plan


def _meta(folder: Path, kind="normal", tool="spatula") -> Path:
    folder.mkdir(parents=True)
    TrialMeta(folder.name, tool, kind, 0.0, 10.0).write(folder)
    (folder / "frames.csv").write_text("frame\n")
    return folder


def test_a_simulated_session_is_its_simulators_plan(smoke_params):
    sheet = SessionSheet(smoke_params, raw="raw")
    bags = sheet.recordings("volume", "sim-smoke")
    assert [r.name for r in bags] == [lift.name for lift in volume_plan(smoke_params["simulate_volume"])]
    assert bags[0].path == f"raw/volume/sim-smoke/{bags[0].name}.bag" and bags[0].format == "bag"
    assert sheet.session_files("volume", "sim-smoke")[-1] == "raw/volume/sim-smoke/lifts.csv"
    trials = sheet.recordings("tool", "sim-smoke")
    plan = tool_plan(smoke_params)
    assert [(r.name, r.kind, r.tool) for r in trials] == [(t.name, t.kind, t.tool) for t in plan]
    # a simulated trial's meta.json stands for its folder, which the simulator writes whole
    assert sheet.ingest_inputs(trials[0]) == ["raw/tool/sim-smoke/nano17.cal", f"{trials[0].path}/meta.json"]
    assert tool_contract.tools(sheet, "shear") == sorted({t.tool for t in plan if t.kind == "shear"})


def test_a_recorded_tool_session_is_read_from_its_trials(smoke_params, tmp_path):
    raw = tmp_path / "raw"
    _meta(raw / "tool/rig/Trial 1", "normal", "spatula")
    _meta(raw / "tool/rig/t2", "shear", "paper_knife")
    (raw / "tool/rig/nano17.cal").write_text("cal")
    (raw / "tool/rig/notes.txt").write_text("a note beside the trials")
    sheet = SessionSheet({**smoke_params, "tool_sessions": ["rig"]}, raw=str(raw))
    trials = sheet.recordings("tool", "rig")
    assert [(r.name, r.kind, r.tool, r.format) for r in trials] == [("Trial 1", "normal", "spatula", "native"),
                                                                    ("t2", "shear", "paper_knife", "native")]
    assert sheet.ingest_inputs(trials[1]) == [f"{raw}/tool/rig/t2/frames.csv", f"{raw}/tool/rig/t2/meta.json",
                                              f"{raw}/tool/rig/nano17.cal"]
    assert f"{raw}/tool/rig/notes.txt" in sheet.session_files("tool", "rig")    # provenance hashes the folder whole
    assert [r.name for r in tool_contract.trials(sheet, "shear")] == ["t2"] and tool_contract.tools(sheet, "normal") == ["spatula"]


def test_a_trial_whose_metadata_is_wrong_is_named(smoke_params, tmp_path):
    raw = tmp_path / "raw"
    trial = _meta(raw / "tool/rig/t1")
    (trial / "meta.json").write_text((trial / "meta.json").read_text().replace('"normal"', '"pressing"'))
    sheet = SessionSheet({**smoke_params, "tool_sessions": ["rig"]}, raw=str(raw))
    with pytest.raises(InputError, match=r"t1/meta.json.*kind"):
        sheet.recordings("tool", "rig")


def test_two_recordings_of_one_name_are_refused(smoke_params, tmp_path):
    raw = tmp_path / "raw"
    _meta(raw / "tool/rig/t1")
    (raw / "tool/rig/t1.bag").write_bytes(b"")           # a ROS bag trial named like the folder
    shutil.copy(raw / "tool/rig/t1/meta.json", raw / "tool/rig/t1.meta.json")
    sheet = SessionSheet({**smoke_params, "tool_sessions": ["rig"]}, raw=str(raw))
    with pytest.raises(InputError, match="two recordings are named 't1'"):
        sheet.recordings("tool", "rig")


def test_a_recorded_drift_session_without_bags_is_named(smoke_params, tmp_path):
    raw = tmp_path / "raw"
    (raw / "drift/bench").mkdir(parents=True)
    sheet = SessionSheet({**smoke_params, "drift_session": "bench"}, raw=str(raw))
    with pytest.raises(InputError, match=r"drift/bench.*no \.bag files"):
        sheet.recordings("drift", "bench")
    shutil.rmtree(raw / "drift/bench")
    with pytest.raises(InputError, match="session folder not found"):
        sheet.recordings("drift", "bench")


def test_the_sessions_command_prints_the_sheet_and_names_a_bad_session(tmp_path, monkeypatch, capsys):
    from tactilepipe.cli.main import main
    params = str(Path(__file__).resolve().parents[2] / "params.yaml")
    monkeypatch.chdir(tmp_path)
    assert main(["sessions", "--params", params, "--scale", "smoke", "--study", "drift"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split("\t") == ["study", "session", "name", "format", "kind", "tool", "path"]
    assert len(out) > 1 and all(row.startswith("drift\tsim-smoke\t") for row in out[1:])
    (tmp_path / "raw/drift/bench").mkdir(parents=True)
    assert main(["sessions", "--params", params, "--scale", "smoke", "--override", '{"drift_session": "bench"}']) == 2
    assert "raw/drift/bench: no .bag files" in capsys.readouterr().err


def test_a_data_set_mixing_simulated_and_recorded_sessions_says_so_in_its_qc():
    from tactilepipe.core.simulated import mixed_data_note
    from tactilepipe.tool.report.data import qc_markdown
    assert mixed_data_note(["sim-default", "sim-default"], "trial") is None
    assert mixed_data_note(["lab", "lab-2"], "trial") is None
    note = mixed_data_note(["sim-default", "lab", "sim-default"], "lift")
    assert note.startswith("Mixed data: 2 lift(s) from simulated session(s) (sim-default) and 1 from recorded "
                           "session(s) (lab)")

    def qc(*sessions):
        trials = [{"trial": f"{s}/t{i}", "tool": "screwdriver_1", "frames": {"digit_left": 3, "digit_right": 3},
                   "pairs": 3, "drops": {}, "clock": {}, "force_min_n": 0.0, "force_max_n": 4.0}
                  for i, s in enumerate(sessions)]
        return qc_markdown({"kind": "normal", "trials": trials, "pairs": 3 * len(trials), "image_size": 32}, "normal")
    assert "Mixed data: 1 trial(s) from simulated session(s) (sim-default) and 2 from recorded session(s) (lab)" \
        in qc("sim-default", "lab", "lab")
    assert "Mixed data" not in qc("sim-default", "sim-default") and "Mixed data" not in qc("lab", "lab")
