"""Does a re-grasp change a finger's frame more than a press does? (Why `no_ref` loses on Fz.)

Without its zero-force reference frame, a model must read the force from the absolute imprint.
This study renders the default session's pressing trials with the simulator (the same frames the
workflow writes, byte for byte) and measures, on the frames as the models see them (grayscale,
resized to ``tool_ingest.stored_size`` by the ingest's own ``preprocess``), the RMS difference in DN:

- re-grasp: the reference frames (frame 0, tip at rest) of two trials of the same tool and pose;
- press at F N: a frame whose tip force is within 0.5 N of F against its own trial's reference;
- rest: a frame of a trial with the tip at rest (< 0.05 N) against that trial's reference
  (camera noise, LED flicker and drift only).

Each is the median over all such pairs, both fingers. With ``--export DIR`` it also writes the
full-resolution BGR frames for ``tactilepipe realism``: ``DIR/rest/`` (every trial's reference
frame) and ``DIR/press_5_10N/<trial>_<finger>/`` (the reference first, then frames at 5-10 N).

Runs on whichever tactilepipe is importable, so the same numbers can be had for another version
of the simulator (``PYTHONPATH=<other checkout>/src python studies/tool_models/study_regrasp.py``). Usage:
    python studies/tool_models/study_regrasp.py [--forces 3 10] [--export DIR]
About 3 minutes on one core at the default scale.
"""

from __future__ import annotations

import argparse
import itertools
from collections import defaultdict
from pathlib import Path

import cv2
import numpy as np

from tactilepipe.core.config import load_params
from tactilepipe.tool.formats import native_layout as layout
from tactilepipe.tool import sim as ts
from tactilepipe.tool.data.ingest import preprocess


def rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a.astype(np.float32) - b.astype(np.float32)) ** 2)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--forces", nargs="*", type=float, default=[3.0, 10.0], help="press forces (N) to measure at")
    ap.add_argument("--export", type=Path, help="write full-resolution frames for `tactilepipe realism` here")
    ap.add_argument("--max-trials", type=int, help="only the first N pressing trials (a quick look)")
    args = ap.parse_args()
    params = load_params()
    size = int(params["tool_ingest"]["stored_size"])
    plan = [s for s in ts.session_plan(params) if s.kind == "normal"][:args.max_trials]
    refs = defaultdict(list)                  # (tool, orientation, insertion, finger) -> reference frames
    press = defaultdict(list)
    rest = []
    for spec in plan:
        out = ts.simulate_trial(spec, params)
        for name in layout.SENSORS:
            frames = out["frames"][name]
            normal = np.abs(out["frame_wrench"][name][:, 2])
            gray = [preprocess(f, size) for f in frames]
            refs[(spec.tool, spec.orientation_deg, spec.insertion_mm, name)].append(gray[0])
            for i in range(1, len(frames)):
                if normal[i] < 0.05:
                    rest.append(rms(gray[i], gray[0]))
                for f in args.forces:
                    if abs(normal[i] - f) < 0.5:
                        press[f].append(rms(gray[i], gray[0]))
            if args.export:
                (args.export / "rest").mkdir(parents=True, exist_ok=True)
                cv2.imwrite(str(args.export / "rest" / f"{spec.name}_{name}.png"), frames[0])
                sub = args.export / "press_5_10N" / f"{spec.name}_{name}"
                chosen = [i for i in range(len(frames)) if 5.0 <= normal[i] <= 10.0]
                if chosen:
                    sub.mkdir(parents=True, exist_ok=True)
                    cv2.imwrite(str(sub / "000_reference.png"), frames[0])
                    for i in chosen:
                        cv2.imwrite(str(sub / f"frame_{i:06d}.png"), frames[i])
    regrasp = [rms(a, b) for group in refs.values() for a, b in itertools.combinations(group, 2)]
    print(f"pressing trials: {len(plan)}; frames as the models see them: grayscale {size} px; RMS difference (DN), "
          "median [25th-75th percentile] (pairs)")
    print(f"re-grasp (two rest frames of one tool and pose)  {_summary(regrasp)}")
    for f in args.forces:
        print(f"press at {f:g} +- 0.5 N vs own reference        {_summary(press[f])}")
    print(f"rest vs own reference (noise, flicker, drift)    {_summary(rest)}")


def _summary(values: list[float]) -> str:
    if not values:
        return "-"
    q = np.percentile(values, [50, 25, 75])
    return f"{q[0]:.2f} [{q[1]:.2f}-{q[2]:.2f}] ({len(values)})"


if __name__ == "__main__":
    main()
