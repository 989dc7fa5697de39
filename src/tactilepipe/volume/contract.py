"""The volume study's contract with the workflow (core/study.py): its sessions, the volume scene,
the files that scene ends in and what the report calls them."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.core.simulated import is_simulated
from tactilepipe.core.study import (Recording, Scene, figure_files, nothing_modelled, recording_file, report_files,
                                    same_stem)
from tactilepipe.volume import scores_layout as scores   # how `tactilepipe diff` reads its scores.json

STUDY = "volume"
SIMULATOR = "volume-simulate"
SCENES = {"volume": Scene("volume", ("papillarray-ingest", "volume-dataset", "volume-split", "volume-train",
                                     "volume-gridsearch", "volume-baseline", "volume-report"))}
PLOT_DATA = ("mu_r2_curve",)
LABELS_FILE = "lifts.csv"          # a session's facts: each lift's bag and volume
SIMULATED_MARK = LABELS_FILE       # the file of a simulated session its DVC stage asks for
DVC_STAGES = {"volume": ["volume"]}
# what the report stage writes under results/<build>/volume/ (volume/report.py), besides its metric rows
OUTPUTS = ["scores.json", "provenance.json", "runtime.json"] + \
    [f"tables/{t}.md" for t in ("table1_r2", "table2_volumes", "unseen_volumes", "runtime", "grid_search")] + \
    figure_files("figures", ("r2_by_modality", "mu_r2_curve", "true_vs_estimated", "error_vs_runtime",
                             "pillar_map"), PLOT_DATA)
REPORT_LABELS = {
    "table1_r2": "Table 1: R² of each force input and the baseline",
    "table2_volumes": "Table 2: estimated volume per true volume",
    "unseen_volumes": "Volumes never seen in training", "runtime": "Fit and prediction time per method",
    "grid_search": "MLP grid search", "r2_by_modality": "R² of each force input and the baseline",
    "mu_r2_curve": "Baseline R² against the friction coefficient μ",
    "true_vs_estimated": "True against estimated volume", "error_vs_runtime": "R² against run time",
    "pillar_map": "Per-pillar forces during a hold"}


def sessions(p: dict) -> list[str]:
    return list(p["volume_sessions"])


def recordings(p: dict, folder: str, session: str) -> tuple[Recording, ...]:
    """A session's bags: those its lifts.csv lists (a simulated one's, from the simulator's plan)."""
    if is_simulated(session):
        from tactilepipe.volume.simulate import session_plan
        stems = [lift.name for lift in session_plan(p["simulate_volume"])]
    else:
        from tactilepipe.volume.labels import read_session_labels
        stems = [Path(row["bag"]).stem for row in read_session_labels(folder)]
    return tuple(Recording(STUDY, session, s, f"{folder}/{s}.bag", "bag") for s in stems)


ingest_inputs = files_on_disk = recording_file       # a bag: its ingest reads it alone
caption_stem = same_stem


def simulated_files(recordings: tuple[Recording, ...], folder: str) -> list[str]:
    return [r.path for r in recordings] + [f"{folder}/{LABELS_FILE}"]


def metric_rows(p: dict) -> list[str]:
    """A row per force input, and the baseline's."""
    return [*p["mlp"]["modalities"], "baseline"]


def report_outputs(scene: str, results: str, p: dict) -> list[str]:
    """What the report stage writes: the metric rows and OUTPUTS."""
    return report_files(scene, results, metric_rows(p), OUTPUTS)


def targets(scene: str, results: str, p: dict, sheet, data_only: bool = False) -> list[str]:
    return report_outputs(scene, results, p)


# --- the compute estimate of `snakemake -n` (pipeline/estimate.py) ---------------------------------
MEASURED_RULES = ("volume_train", "volume_baseline")
modelled_report = nothing_modelled


def measured_seconds(p: dict, rule: str, wildcards: dict, runtimes) -> float | None:
    """A fit job's time in the last build: its method's fit_s per fold x folds (``runtimes(scene)``)."""
    method = wildcards["modality"] if rule == "volume_train" else "baseline"
    fit_s = runtimes("volume").get(method, {}).get("fit_s")
    return None if fit_s is None else fit_s * p["folds"]["n_folds"]

