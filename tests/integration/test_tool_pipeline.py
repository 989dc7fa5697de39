"""Simulated tool trials through every importer, ingest and sync, checked against the truth."""

from __future__ import annotations

import numpy as np
import pytest

from support import tool_sim
from tactilepipe.core.config import load_params
from tactilepipe.tool import sim as ts
from tactilepipe.tool.data.dataset import build_tool_dataset
from tactilepipe.tool.formats.trials import list_trials, open_trial
from tactilepipe.tool.data.ingest import ingest_trial
from tactilepipe.tool.data.loader import ToolFrames
from support.ros_writer import write_ros_trial
from support.project import REPO


@pytest.fixture(scope="module")
def params():
    return load_params(REPO / "params.yaml", {"scale": "smoke"})


@pytest.fixture(scope="module")
def native_session(tmp_path_factory, params):
    session = tmp_path_factory.mktemp("raw") / "sim-smoke"
    plan = [s for s in ts.session_plan(params) if s.kind == "normal"][:2]
    ts.write_session_calibration(session, params)
    for spec in plan:
        ts.write_trial(session, spec, params)
    return session, plan


def test_synced_labels_match_the_force_at_exposure(native_session, params, tmp_path):
    session, plan = native_session
    shards = []
    for name, path, fmt in list_trials(session):
        assert fmt == "native"
        shard = tmp_path / f"{name}.parquet"
        ingest_trial(open_trial(path, fmt), shard, 32, params["tool_ingest"])
        shards.append(shard)
    build_tool_dataset(shards, "normal", tmp_path / "data", params["tool_sync"])
    data = ToolFrames(tmp_path / "data", "normal")
    for k, spec in enumerate(plan):
        truth = ts.simulate_trial(spec, params)
        # the force each frame really saw, averaged over the two fingers' exposures
        true_normal = {n: -w[:, 2] for n, w in truth["frame_wrench"].items()}
        rows = data.samples[data.samples["trial_index"] == k]
        left_ns = truth["host_ns"]["digit_left"]
        idx = np.clip(np.searchsorted(left_ns, rows["t_ns"].to_numpy()), 0, len(left_ns) - 1)
        expected = true_normal["digit_left"][idx]
        err = np.abs(rows["normal"].to_numpy() - expected)
        peak = expected.max()
        # ADC resolution (~0.07 N), 15 Hz interpolation and the half-frame pairing window
        assert np.median(err) < 0.1 + 0.02 * peak, (spec.name, np.median(err), peak)
        assert err.max() < 0.25 * peak + 0.3, (spec.name, err.max(), peak)


def test_public_layout_runs_through_the_same_ingest(params, tmp_path):
    root = tmp_path / "public"
    names = tool_sim.simulate_public_session(root, params, n_trials=4)
    trials = list_trials(root)
    assert {fmt for _, _, fmt in trials} == {"public"} and len(trials) == len(names)
    shards = []
    for name, path, fmt in trials:
        raw = open_trial(path, fmt)
        shard = tmp_path / f"{name}.parquet"
        ingest_trial(raw, shard, 32, params["tool_ingest"])
        shards.append((shard, raw.kind))
    kinds = {k for _, k in shards}
    for kind in kinds:
        build_tool_dataset([s for s, k in shards if k == kind], kind, tmp_path / f"data_{kind}", params["tool_sync"])
        data = ToolFrames(tmp_path / f"data_{kind}", kind)
        assert len(data) > 0 and (data.labels >= -0.5).all()        # magnitudes, in the right sign
        assert data.labels.max() > 1.0


@pytest.mark.parametrize("fmt", ["ros1", "ros2_sqlite3", "ros2_mcap"])
def test_ros_bags_run_through_the_same_ingest(native_session, params, tmp_path, fmt):
    session, plan = native_session
    raw = open_trial(session / plan[0].name, "native")
    n = 20
    frames = {s: [raw.frames[s].load(i) for i in range(n)] for s in raw.frames}
    bag = tmp_path / ("trial.bag" if fmt == "ros1" else "trial")
    write_ros_trial(bag, frames["digit_left"], frames["digit_right"],
                    {s: raw.frames[s].host_ns[:n] for s in raw.frames}, raw.force_host_ns, raw.force_n,
                    fmt, compressed=True)
    meta = {"trial": "trial", "tool": raw.tool, "kind": raw.kind, "orientation_deg": raw.orientation_deg,
            "insertion_mm": raw.insertion_mm}
    (tmp_path / ("trial.meta.json")).write_text(__import__("json").dumps(meta))
    trials = list_trials(tmp_path)
    ros = [t for t in trials if t[2] == "ros"]
    assert len(ros) == 1
    info = ingest_trial(open_trial(ros[0][1], "ros"), tmp_path / "shard.parquet", 32, params["tool_ingest"])
    assert info["frames"] == {"digit_left": n, "digit_right": n}
    assert info["clock"]["method"] == "ros_header_stamps"
