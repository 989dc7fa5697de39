"""Simulator probes for tests: a trial's mechanics without rendering, frames at chosen tip loads, a
whole session in one call, and a session written in the public dataset's layout."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from support.public_formats import write_public_trial
from tactilepipe.core.atomic import write_text
from tactilepipe.tool.formats import native_layout as layout
from tactilepipe.tool.sim.plan import TrialSpec, session_plan, sim_group, trial_rng, write_session_calibration
from tactilepipe.tool.sim.trial import Trial, write_trial


def trial_mechanics(spec: TrialSpec, params: dict) -> dict:
    """The trial's forces and pad loads at every frame, without rendering (cheap checks).

    Returns frame_wrench (sensor -> (n, 6) Nano17 reading at each exposure), pads (sensor ->
    per-frame pad state) and max_traction_ratio (the largest |T| / (mu N) of either pad).
    """
    trial = Trial(spec, params)
    return {"frame_wrench": {name: trial.sensor_wrench(trial.exposure[s]) for s, name in enumerate(layout.SENSORS)},
            "pads": {name: {k: v[:, s] for k, v in trial.pad_state[s].items() if k != "q"}
                     for s, name in enumerate(layout.SENSORS)},
            "max_traction_ratio": float(max(st["traction_ratio"].max() for st in trial.pad_state))}


def write_session(session_dir: str | Path, params: dict, trials: list[str] | None = None) -> list[TrialSpec]:
    """nano17.cal and every trial of the plan (or only the named ones) into ``session_dir``."""
    plan = session_plan(params)
    if trials is not None:
        plan = [s for s in plan if s.name in set(trials)]
    write_session_calibration(session_dir, params)
    for spec in plan:
        write_trial(session_dir, spec, params)
    return plan


def render_at_forces(spec: TrialSpec, params: dict, normal_n, reaction_n=None, noise: bool = False) -> dict:
    """Frames of both sensors at the trial's grasp for given tip loads (tests and figures).

    normal_n: tip normal forces (N), the tip pinned as in a pressing trial; or reaction_n: (T, 3)
    reactions on the tip in the gripper frame (n, u, z). Index 0 of the result is not special:
    the zero-force reference is the frame for 0 N.
    """
    trial = Trial(spec, params, noise=noise)
    if reaction_n is None:
        reaction_n = trial.grasp.pinned_reaction(np.asarray(normal_n, float), trial.mu_tip)
    state = trial.grasp.pads(np.asarray(reaction_n, float))
    out = {"pads": state, "no_grasp": {}}
    for s, name in enumerate(layout.SENSORS):
        c, r = trial.contacts[s], trial.renderers[s]
        frames = []
        for i in range(len(reaction_n)):
            h = c.height(state["depth"][i, s])
            disp = c.displacement(state["du"][i, s], state["dz"][i, s])
            frames.append(r.render(h, disp, rng=trial._frame_rng(s, i) if noise else None))
        out[name] = np.stack(frames)
        out["no_grasp"][name] = trial.no_grasp_frame(s)
    out["gel_height"] = {name: trial.renderers[s].gel_height(trial.contacts[s].height(state["depth"][-1, s]))
                         for s, name in enumerate(layout.SENSORS)}
    return out


def simulate_public_session(root: str | Path, params: dict, seed: int | None = None,
                            n_trials: int | None = None) -> list[str]:
    """Write simulated trials in the public dataset's layout (data_normal/, data_shear/).

    Frames at 15 FPS (every ``public.frame_stride``-th camera frame), each paired with the force
    at its exposure: normal trials as the public rig's raw Arduino count of the normal force,
    shear trials as fx,fy,fz in N. Returns the trial folder names written.
    """
    if seed is not None:
        params = {**params, "seed": int(seed)}
    stride = int(sim_group(params)["public"]["frame_stride"])
    plan = session_plan(params)[:n_trials]
    names = []
    for spec in plan:
        trial = Trial(spec, params)
        idx = np.arange(0, trial.n_frames, stride)
        left = [trial.frame(0, i) for i in idx]
        right = [trial.frame(1, i) for i in idx]
        wrench = trial.sensor_wrench(trial.exposure[0][idx])
        noise = trial_rng(params["seed"], spec, 50).standard_normal((len(idx), 3)) * 0.02
        if spec.kind == "normal":
            forces = np.abs(wrench[:, 2]) + noise[:, 2]
        else:
            forces = wrench[:, :3] + noise
        write_public_trial(root, spec.name, left, right, forces, spec.kind)
        names.append(spec.name)
    # the tools and poses, which the layout itself does not record (tool/formats/trials.py)
    rows = ["trial,tool,orientation_deg,insertion_mm"] + [
        f"{s.name},{s.tool},{s.orientation_deg:g},{s.insertion_mm:g}" for s in plan]
    write_text(Path(root) / "trials.csv", "\n".join(rows) + "\n")
    return names
