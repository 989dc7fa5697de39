"""The drift study's contract with the workflow (core/study.py): its session, the drift scene, the
files that scene ends in and what the report calls them."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.core.errors import InputError
from tactilepipe.core.simulated import is_simulated
from tactilepipe.core.study import (Recording, Scene, figure_files, nothing_measured, nothing_modelled, recording_file,
                                    report_files, same_stem)
from tactilepipe.drift import scores_layout as scores   # how `tactilepipe diff` reads its scores.json
from tactilepipe.drift import RUNS, SESSION_META

STUDY = "drift"
SIMULATOR = "drift-simulate"
SCENES = {"drift": Scene("drift", ("papillarray-ingest", "drift-report"))}
PLOT_DATA = ("drift_curves",)
SIMULATED_MARK = SESSION_META       # the file of a simulated session its DVC stage asks for
DVC_STAGES = {"drift": ["drift"]}
# what the report stage writes under results/<build>/drift/ (drift/analyse.py), besides its metric rows
OUTPUTS = ["scores.json", "provenance.json", "fits.md"] + figure_files("figures", ["drift_curves"], PLOT_DATA)
REPORT_LABELS = {"fits": "Drift fits and recalibration interval", "drift_curves": "Drift with the fitted curves"}


def sessions(p: dict) -> list[str]:
    return [p["drift_session"]]


def recordings(p: dict, folder: str, session: str) -> tuple[Recording, ...]:
    """A session's bags: every .bag of its folder (a simulated one's, from the simulator's plan)."""
    if is_simulated(session):
        from tactilepipe.drift.simulate import session_plan
        stems = session_plan(p)
    else:
        if not Path(folder).is_dir():
            raise InputError(folder, "session folder not found (params.yaml drift_session)")
        stems = sorted(bag.stem for bag in Path(folder).glob("*.bag"))
        if not stems:
            raise InputError(folder, "no .bag files: the drift session's recordings are its bags")
    return tuple(Recording(STUDY, session, s, f"{folder}/{s}.bag", "bag") for s in stems)


ingest_inputs = files_on_disk = recording_file       # a bag: its ingest reads it alone
caption_stem = same_stem


def simulated_files(recordings: tuple[Recording, ...], folder: str) -> list[str]:
    return [r.path for r in recordings] + [f"{folder}/{SESSION_META}"]


def metric_rows(p: dict) -> list[str]:
    """A row per run of the session."""
    return list(RUNS)


def report_outputs(scene: str, results: str, p: dict) -> list[str]:
    """What the report stage writes: the metric rows and OUTPUTS."""
    return report_files(scene, results, metric_rows(p), OUTPUTS)


def targets(scene: str, results: str, p: dict, sheet, data_only: bool = False) -> list[str]:
    return report_outputs(scene, results, p)


# --- the compute estimate of `snakemake -n` (pipeline/estimate.py): nothing timed or modelled -------
MEASURED_RULES: tuple[str, ...] = ()
measured_seconds = nothing_measured
modelled_report = nothing_modelled
