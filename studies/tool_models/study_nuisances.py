"""Which of the simulator's per-grasp nuisances make a finger's reference frame worth more than the
second finger? (Why `no_ref` loses to `single` on normal force, and gains little on shear.)

A trained network mixes what its inputs hold with how well it trains on them. This study reads
the inputs alone: it simulates the default session in memory, renders every ``--step``-th frame of
both fingers as the models see it (the ingest's own grayscale ``preprocess`` at
``tool_ingest.stored_size``, then area-resized to the model's ``tool_train.image_size``), and fits a
k-nearest-neighbour regression (no training, no seed) on each variant's inputs:

- full: both fingers' change from their own reference frame (frame 0, tip at rest);
- single: the left finger's change from its reference;
- no_ref: both fingers' current frames, no reference.

It scores them over ``--repeats`` trial-grouped, tool-stratified splits (15 % of each tool's
trials tested), and repeats that with nuisances of the grasp and the light switched off in the
simulator's parameters (every random draw is still made, so all else stays the same):

- as built: the default parameters;
- no insertion jitter: the hand grips the handle at the same height every time;
- no light drift: no LED warm-up and no slow drift of the lights between trials;
- neither: both of the above.

Usage:
    python studies/tool_models/study_nuisances.py [--step 3] [--repeats 8] [--k 10]
About 4 minutes on one core at the default scale (each condition simulates 144 trials).
"""

from __future__ import annotations

import argparse
import copy
import time
from pathlib import Path

import cv2
import numpy as np

from tactilepipe.core.config import load_params
from tactilepipe.tool.data.ingest import preprocess
from tactilepipe.tool.sim.plan import session_plan
from tactilepipe.tool.sim.trial import Trial

REPO = Path(__file__).resolve().parents[2]
CONDITIONS = {
    "as built": {},
    "no insertion jitter": {"grasp": {"insertion_jitter_mm": 0.0}},
    "no light drift": {"render": {"drift_dn": 0.0, "warmup_dn": 0.0}},
    "neither": {"grasp": {"insertion_jitter_mm": 0.0}, "render": {"drift_dn": 0.0, "warmup_dn": 0.0}},
}


def simulate(params: dict, step: int) -> dict:
    """Every ``step``-th frame of every trial: the model's view of both fingers, and the labels."""
    stored, size = params["tool_ingest"]["stored_size"], params["tool_train"]["image_size"]
    sign = params["tool_sync"]["normal_sign"]
    rows = {"trial": [], "shear_trial": [], "tool": [], "normal": [], "shear": [], "frames": [], "ref": []}
    for i, spec in enumerate(session_plan(params)):
        trial = Trial(spec, params)
        idx = np.arange(0, trial.n_frames, step)
        wrench = trial.sensor_wrench(trial.exposure[0][idx])
        frames = np.stack([[cv2.resize(preprocess(trial.frame(f, j), stored), (size, size),
                                       interpolation=cv2.INTER_AREA) for f in range(2)] for j in idx])
        frames = frames.reshape(len(idx), 2, -1).astype(np.float32)
        rows["frames"].append(frames)
        rows["ref"].append(np.repeat(frames[:1], len(idx), axis=0))        # frame 0: the tip at rest
        rows["normal"].append(sign * wrench[:, 2])
        rows["shear"].append(np.hypot(wrench[:, 0], wrench[:, 1]))
        for key, value in (("trial", i), ("shear_trial", spec.kind == "shear"), ("tool", spec.tool)):
            rows[key] += [value] * len(idx)
    return {k: np.concatenate(v) if k in ("frames", "ref", "normal", "shear") else np.array(v)
            for k, v in rows.items()}


def inputs(data: dict) -> dict[str, np.ndarray]:
    cur, ref = data["frames"], data["ref"]
    change = cur - ref
    return {"full": change.reshape(len(cur), -1), "single": change[:, 0], "no_ref": cur.reshape(len(cur), -1)}


def knn(x_train: np.ndarray, y_train: np.ndarray, x_test: np.ndarray, k: int) -> np.ndarray:
    d2 = (x_test ** 2).sum(1)[:, None] - 2 * x_test @ x_train.T + (x_train ** 2).sum(1)[None]
    return y_train[np.argpartition(d2, k, axis=1)[:, :k]].mean(1)


def scores(data: dict, label: str, repeats: int, k: int) -> dict[str, np.ndarray]:
    """Test MAE of each input over the repeated splits (the same test trials for every input)."""
    rows = np.flatnonzero(data["shear_trial"] == (label == "shear"))
    trial, tool, y = data["trial"][rows], data["tool"][rows], data[label][rows]
    x = {name: v[rows] for name, v in inputs(data).items()}
    out = {name: [] for name in x}
    for r in range(repeats):
        rng = np.random.default_rng(r)
        test = []
        for name in np.unique(tool):
            trials = rng.permutation(np.unique(trial[tool == name]))
            test += list(trials[:max(1, round(0.15 * len(trials)))])
        held = np.isin(trial, test)
        for name, v in x.items():
            out[name].append(float(np.abs(knn(v[~held], y[~held], v[held], k) - y[held]).mean()))
    return {name: np.array(v) for name, v in out.items()}


def difference(a: np.ndarray, b: np.ndarray) -> str:
    d = a - b
    return f"{d.mean():+.3f} (sd {d.std(ddof=1):.3f})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--step", type=int, default=3, help="every step-th frame of each trial")
    ap.add_argument("--repeats", type=int, default=8, help="trial-grouped, tool-stratified splits")
    ap.add_argument("--k", type=int, default=10, help="neighbours of the regression")
    args = ap.parse_args()
    base = load_params(REPO / "params.yaml", {"scale": "default"})
    print(f"kNN (k={args.k}) test MAE in N, mean over {args.repeats} splits; differences paired, worse - better")
    print("| condition | target | full | single | no_ref | no_ref - full | no_ref - single | single - full |")
    print("|---|---|---|---|---|---|---|---|")
    for name, change in CONDITIONS.items():
        params = copy.deepcopy(base)
        for group, values in change.items():
            params["simulate_tool"][group].update(values)
        t0 = time.time()
        data = simulate(params, args.step)
        for label in ("normal", "shear"):
            s = scores(data, label, args.repeats, args.k)
            print(f"| {name} | {label} | {s['full'].mean():.3f} | {s['single'].mean():.3f} | {s['no_ref'].mean():.3f} | "
                  f"{difference(s['no_ref'], s['full'])} | {difference(s['no_ref'], s['single'])} | "
                  f"{difference(s['single'], s['full'])} |", flush=True)
        print(f"<!-- {name}: {time.time() - t0:.0f} s -->", flush=True)


if __name__ == "__main__":
    main()
