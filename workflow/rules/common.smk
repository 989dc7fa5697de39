# Shared set-up: the validated parameters, how rules call the CLI, and which files a scene needs.
import json
import shlex
import sys
from pathlib import Path

import yaml

from tactilepipe.config import resolve
from tactilepipe.errors import TactilepipeError
from tactilepipe.volume.simulate import read_session_labels, session_plan
from tactilepipe.drift.simulate import session_plan as drift_plan

# `config` is params.yaml plus any --config overrides; validate and resolve the scale up front
# so a wrong key or type stops the run before any job starts.
with open("params.yaml") as _fh:
    _FILE_PARAMS = yaml.safe_load(_fh)
# Overrides given with --config are handed to every CLI call, so each stage sees the same values.
OVERRIDES = {k: v for k, v in config.items() if _FILE_PARAMS.get(k) != v}
try:
    P = resolve(dict(config), "params.yaml (+ --config)", OVERRIDES)
except TactilepipeError as exc:
    raise WorkflowError(str(exc)) from None
CLI = f"{shlex.quote(sys.executable)} -m tactilepipe"
PARAMS_ARGS = f"--override {shlex.quote(json.dumps(OVERRIDES, sort_keys=True))}" if OVERRIDES else ""

LOGS = "results/logs"
VOLUME = "results/volume"
DRIFT = "results/drift"
DRIFT_SESSION = f"sim-{P['scale']}"


def is_simulated(session):
    return session.startswith("sim-")


def volume_bag_stems(session):
    """Bags of a volume session: planned by the simulator, or listed in the session's lifts.csv."""
    if is_simulated(session):
        return [lift.name for lift in session_plan(P["simulate_volume"])]
    return [Path(row["bag"]).stem for row in read_session_labels(f"raw/volume/{session}")]


def volume_shards():
    return [f"{VOLUME}/shards/{s}/{stem}.parquet" for s in P["volume_sessions"] for stem in volume_bag_stems(s)]


def drift_shards():
    return [f"{DRIFT}/shards/{DRIFT_SESSION}/{name}.parquet" for name in drift_plan(P)]


VOLUME_TARGETS = [
    f"{VOLUME}/metrics.json",
    f"{VOLUME}/tables/table1_r2.md",
    f"{VOLUME}/tables/table2_volumes.md",
    f"{VOLUME}/tables/unseen_volumes.md",
    f"{VOLUME}/tables/runtime.md",
    f"{VOLUME}/tables/grid_search.md",
    f"{VOLUME}/figures/r2_by_modality.png",
    f"{VOLUME}/figures/mu_r2_curve.png",
    f"{VOLUME}/figures/true_vs_estimated.png",
    f"{VOLUME}/figures/error_vs_runtime.png",
    f"{VOLUME}/figures/pillar_map.png",
]
DRIFT_TARGETS = [f"{DRIFT}/metrics.json", f"{DRIFT}/fits.md", f"{DRIFT}/figures/drift_curves.png"]


def scene_targets(scenes):
    targets = {"volume": VOLUME_TARGETS, "drift": DRIFT_TARGETS}
    missing = [s for s in scenes if s not in targets]
    if missing:
        raise WorkflowError(f"scenes {missing} are not built by this workflow yet (available: {sorted(targets)})")
    return [t for s in scenes for t in targets[s]]
