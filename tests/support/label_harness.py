"""The label error harness: simulated sessions with legitimate variations and injected faults, run
through ingest and the data set, every kept trial's labels measured against the simulator's truth.

The contract it checks (docs/robustness.md, "The label error budget"):
- a clean or legitimately varied session keeps every trial, each within the budget;
- a fault either leaves its trial out (or refuses it) with a reason, or leaves its labels within
  the budget (the fault did not reach them); a kept trial over the budget is an overrun, a
  failure nobody named;
- the other trials of a faulty session are kept, within the budget.

``session`` writes a session (one tool, 3 poses x 3 presses by default: the smallest session the
witnesses must work on); ``run_case`` copies it, applies a fault to one trial, ingests every
trial (the faulty one and the data set through the real command line when ``cli`` is set) and
returns what happened to each trial.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from support.label_oracle import budget, label_errors
from support.project import ENV, REPO
from tactilepipe.core.config import deep_merge, load_params
from tactilepipe.core.errors import InputError
from tactilepipe.tool.data.dataset import build_tool_dataset
from tactilepipe.tool.data.ingest import ingest_trial
from tactilepipe.tool.formats.trials import open_trial
from tactilepipe.tool.sim.plan import TrialSpec, session_plan, write_session_calibration
from tactilepipe.tool.sim.trial import Trial, write_trial

SESSION = {"tool_ingest": {"stored_size": 32},
           "simulate_tool": {"tools_used": ["screwdriver_1"], "poses_per_tool": 3, "normal_trials_per_pose": 3,
                             "shear_trials_per_pose": 0, "frames_per_trial": 72}}
# legitimate variations of a lab's recordings: every trial must be kept, within the budget
VARIATIONS = {
    "light presses": {"simulate_tool": {"press": {"peak_force_n": [0.3, 0.8]}}},
    "slow ramps": {"simulate_tool": {"frames_per_trial": 150, "press": {"rise_s": [2.0, 2.8], "fall_s": [1.5, 2.0],
                                                                         "hold_s": [0.0, 0.3]}}},
    # the simulated gel's modulus is 1 MPa: 3 and 6 times stiffer barely move the images
    "stiff gels x3": {"simulate_tool": {"grasp": {"e_star_mpa": 3.0}}},
    "stiff gels x6": {"simulate_tool": {"grasp": {"e_star_mpa": 6.0}}},
}


def parameters(*overrides: dict, seed: int | None = None) -> dict:
    merged = {"scale": "default"}
    for o in (SESSION, *overrides):
        merged = deep_merge(merged, o)
    if seed is not None:
        merged["seed"] = seed
    return load_params(REPO / "params.yaml", merged)


@dataclass
class Session:
    folder: Path
    trials: dict[str, Trial] = field(default_factory=dict)    # name -> the simulated trial (the oracle)
    params: dict = field(default_factory=dict)


def session(folder: Path, params: dict, rate_of: Callable[[TrialSpec], float] | None = None) -> Session:
    """Every trial of the plan written into ``folder``; ``rate_of`` gives a trial its own camera
    rate (a mixed-rate session), declared in its meta.json as the rig would."""
    write_session_calibration(folder, params)
    out = Session(folder, params=params)
    for spec in session_plan(params):
        p = params
        if rate_of is not None:
            p = deep_merge(params, {"simulate_tool": {"camera": {"fps": rate_of(spec)}}})
        write_trial(folder, spec, p)
        out.trials[spec.name] = Trial(spec, p)
    return out


def cli(*args: str) -> subprocess.CompletedProcess:
    env = {**ENV, "PYTHONPATH": str(REPO / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.run([sys.executable, "-m", "tactilepipe", *args], env=env, capture_output=True, text=True,
                          timeout=600)


def _ingest(trial_dir: Path, shard: Path, params: dict, via_cli: bool, cli_params: list[str]) -> str | None:
    """None when the shard was written, else the refusal's message."""
    if via_cli:
        proc = cli("tool-ingest", *cli_params, str(trial_dir), "--format", "native", "--out", str(shard))
        return None if proc.returncode == 0 else proc.stderr.strip().splitlines()[-1]
    try:
        ingest_trial(open_trial(trial_dir, "native"), shard, params["tool_ingest"]["stored_size"], params["tool_ingest"])
    except InputError as exc:
        return str(exc)
    return None


def run_case(base: Session, work: Path, overrides: dict, fault: Callable[[Path], None] | None = None,
             faulty: str | None = None, via_cli: bool = False, shards: dict[str, Path] | None = None) -> dict:
    """What happens to each trial of ``base`` with ``fault`` applied to trial ``faulty``:
    {trial: {"status": kept | left out | refused, "reason": str, "error": {...}, "over": str | None}}.
    ``overrides``: the parameters the session was written with (the pipeline reads the same file);
    ``shards``: clean shards of the other trials, ingested already."""
    folder = work / "raw" / base.folder.name
    shutil.copytree(base.folder, folder)
    if fault is not None:
        fault(folder / faulty)
    cli_params = ["--params", str(REPO / "params.yaml"), "--scale", "default",
                  "--override", json.dumps(deep_merge(SESSION, overrides))]
    result, written = {}, []
    for name in base.trials:
        shard = (shards or {}).get(name) if name != faulty else None
        if shard is None:
            shard = work / "shards" / f"{name}.parquet"
            shard.parent.mkdir(parents=True, exist_ok=True)
            why = _ingest(folder / name, shard, base.params, via_cli and name == faulty, cli_params)
            if why is not None:
                result[name] = {"status": "refused", "reason": why}
                continue
        written.append(shard)
    data = work / "data"
    if via_cli:
        proc = cli("tool-dataset", *cli_params, "--kind", "normal", "--shards", *map(str, written),
                   "--out-dir", str(data))
        if proc.returncode != 0:
            raise AssertionError(f"tool-dataset failed: {proc.stderr[-2000:]}")
    else:
        build_tool_dataset(written, "normal", data, base.params["tool_sync"])
    qc = json.loads((data / "qc.json").read_text())
    for entry in qc["dropped_trials"]:
        result[entry["trial"].split("/")[-1]] = {"status": "left out", "reason": entry["reason"]}
    for name, error in label_errors(data, base.trials).items():
        b = budget(error["peak"])
        over = [f"{k} {error[k]:.3f} > {b[k]:.3f} N" for k in ("mae", "p95") if error[k] > b[k]]
        result[name] = {"status": "kept", "error": error, "over": "; ".join(over) or None}
    return result
