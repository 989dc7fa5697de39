"""The plan of a simulated tool-force session: which trials, their seeds, and the Nano17 calibration.

Determinism: every random draw comes from np.random.SeedSequence([seed, stream, ...]); a trial's
draws depend only on the seed, the tool name, the pose, the kind and the trial number, so the
same seed gives byte-identical files whatever else is in the plan.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tactilepipe.core.errors import ConfigError
from tactilepipe.tool.formats import native_layout as layout

G = 9.81
SESSION_EPOCH_S = 1_767_225_600     # 2026-01-01T00:00:00Z: simulated sessions start here
KINDS = ("normal", "shear")
STREAM_CAL, STREAM_RIG, STREAM_LOOK, STREAM_TRIAL = 4001, 4002, 4003, 4004


@dataclass(frozen=True)
class TrialSpec:
    """One recorded trial: what the lab notes down (tool, nominal grasp pose, kind)."""
    name: str
    tool: str
    kind: str                  # "normal" (pressing) or "shear" (sliding)
    orientation_deg: float
    insertion_mm: float
    pose_index: int
    trial_index: int = 0       # number of this trial among the same tool, pose and kind
    session_index: int = 0     # position in the recording session (sets the host clock)


def sim_group(params: dict) -> dict:
    try:
        sim = params["simulate_tool"]
    except (KeyError, TypeError):
        raise ConfigError("params: the simulate_tool group is missing") from None
    return {k: v for k, v in sim.items() if k != "scales"}


def session_plan(params: dict) -> list[TrialSpec]:
    """All trials of a simulated session in recording order: per tool, per pose, normal then shear."""
    sim = sim_group(params)
    poses = sim["poses"]
    if sim["poses_per_tool"] > len(poses):
        raise ConfigError(f"simulate_tool.poses_per_tool={sim['poses_per_tool']} exceeds the "
                          f"{len(poses)} poses listed in simulate_tool.poses")
    specs: list[TrialSpec] = []
    for tool in sim["tools_used"]:
        if tool not in sim["tools"]:
            raise ConfigError(f"simulate_tool.tools_used: unknown tool '{tool}' "
                              f"(known: {sorted(sim['tools'])})")
        for p in range(sim["poses_per_tool"]):
            pose = poses[p]
            for kind, count in (("normal", sim["normal_trials_per_pose"]),
                                ("shear", sim["shear_trials_per_pose"])):
                for k in range(count):
                    specs.append(TrialSpec(f"{tool}_p{p:02d}_{kind}{k:02d}", tool, kind,
                                           float(pose["orientation_deg"]), float(pose["insertion_mm"]),
                                           p, k, len(specs)))
    return specs


def frames_per_trial(params: dict, kind: str) -> int:
    """Camera frames of a pressing ("normal") or sliding ("shear") trial."""
    sim = sim_group(params)
    return int(sim["frames_per_trial"] if kind == "normal" else sim["shear_frames_per_trial"])


def trial_rng(seed: int, spec: TrialSpec, sub: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(
        [seed, STREAM_TRIAL, zlib.crc32(spec.tool.encode()), spec.pose_index, spec.trial_index,
         KINDS.index(spec.kind), sub]))


def uniform(rng: np.random.Generator, bounds) -> float:
    lo, hi = bounds
    return float(rng.uniform(lo, hi))


def calibration_matrix(params: dict) -> np.ndarray:
    """The session's 6x6 Nano17 calibration (N or N*mm per volt): diagonal-dominant, small cross-talk."""
    cal = sim_group(params)["calibration"]
    rng = np.random.default_rng(np.random.SeedSequence([params["seed"], STREAM_CAL]))
    full = np.array(list(cal["full_scale_n"]) + list(cal["full_scale_nmm"]), float)
    diag = full / cal["full_scale_v"] * (1 + cal["gain_rel_std"] * rng.standard_normal(6))
    off = cal["crosstalk_rel"] * rng.standard_normal((6, 6)) * diag[:, None]
    np.fill_diagonal(off, 0.0)
    return np.diag(diag) + off


def write_session_calibration(session_dir: str | Path, params: dict) -> None:
    """nano17.cal of the session (the same matrix write_trial encodes the forces with)."""
    layout.write_calibration(Path(session_dir) / "nano17.cal", calibration_matrix(params),
                             serial=f"FT-SIM-{params['seed'] % 10000:04d}")
