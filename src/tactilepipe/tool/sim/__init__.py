"""The tool-rig simulator: writes what the real rig writes (two DIGITs' frames, the Nano17's serial
log, meta.json, nano17.cal), the true tip force only through the force log.

plan.py: which trials and their seeds; motion.py: force profiles and grasp mechanics; trial.py:
one trial (physics, frames, serial log) and its files; render.py: DIGIT frames; background.py:
the no-contact frame; realism.py: real-vs-simulated frame statistics.
"""

from tactilepipe.tool.sim.plan import (KINDS, TrialSpec, calibration_matrix, frames_per_trial, session_plan,
                                       write_session_calibration)
from tactilepipe.tool.sim.trial import Trial, simulate_trial, write_trial

__all__ = ["KINDS", "Trial", "TrialSpec", "calibration_matrix", "frames_per_trial", "session_plan", "simulate_trial",
           "write_session_calibration", "write_trial"]
