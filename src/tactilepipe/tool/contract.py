"""The tool study's contract with the workflow (core/study.py): its sessions of trials, the two
tool scenes, the files each ends in and what the report calls them."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.core.simulated import is_simulated
from tactilepipe.core.study import Recording, Scene, figure_files, report_files
from tactilepipe.tool import scores_layout as scores   # how `tactilepipe diff` reads its scores.json
from tactilepipe.tool.scenes import TOOL_SCENES, scene_label

STUDY = "tool"
SIMULATOR = "tool-simulate"
SCENES = {name: Scene("tool", ("tool-ingest", "tool-dataset", "tool-split", "tool-train", "tool-model-report"))
          for name in TOOL_SCENES}
PLOT_DATA = ("error_vs_runtime", "intervals")
CALIBRATION = "nano17.cal"          # a session's Nano17 calibration, shared by its trials
SIMULATED_MARK = CALIBRATION       # the file of a simulated session its DVC stage asks for
# the data of both scenes apart from their models: new recordings re-make the data in a stage of its own
DVC_STAGES = {"tool_data": ["tool_data"], "tool_models": list(TOOL_SCENES)}
DATA_FIGURES = ["force_histogram", "force_profiles", "rmse_vs_force", "pressing_strip"]
REPORT_LABELS = {
    "qc": "Quality control of the data stages",
    "force_histogram": "Histogram of the force labels", "force_profiles": "Force profiles of the trials",
    "rmse_vs_force": "Image change against force", "pressing_strip": "DIGIT frames across one press",
    "sorted_predictions": "Test predictions sorted by true force",
    "over_time": "Predicted and true force over time", "per_tool": "Error per tool",
    "per_tool_table": "Error per tool", "window_heatmap": "Error per force window and variant",
    "per_window": "Error per force window", "regression": "Predicted against true force",
    "error_vs_runtime": "Error against run time", "runtime": "Training time and inference latency",
    "intervals": "Variants and baselines over the repeated splits",
    "intervals_table": "Variants and baselines over the repeated splits",
    "variants": "Every variant and baseline, one split", "differences": "Paired differences between variants",
    "paper_orderings": "Study 000's orderings of the variants, judged",
    "loto": "Leave one tool out: error per held-out tool",
    "loto_table": "Leave one tool out: error per held-out tool"}


def figures(folder: str, names) -> list[str]:
    """Every file of each figure of ``names`` under ``folder`` (PNG, SVG and, for PLOT_DATA, CSV)."""
    return figure_files(folder, names, PLOT_DATA)


def model_figures(p: dict) -> list[str]:
    return ["sorted_predictions", "over_time", "per_tool", "window_heatmap", "regression", "error_vs_runtime",
            "intervals"] + (["loto"] if p["tool_train"]["loto"] else [])


def model_tables(p: dict) -> list[str]:
    return ["variants", "intervals", "differences", "paper_orderings", "per_tool", "per_window", "runtime"] + \
        (["loto"] if p["tool_train"]["loto"] else [])


# --- the session reader ----------------------------------------------------------------------------
def sessions(p: dict) -> list[str]:
    return list(p["tool_sessions"])


def recordings(p: dict, folder: str, session: str) -> tuple[Recording, ...]:
    """A session's trials: the simulator's plan for a simulated session, else every trial folder
    or bag on the disk, with its kind and tool from its own metadata."""
    if is_simulated(session):
        from tactilepipe.tool.sim import session_plan
        return tuple(Recording(STUDY, session, t.name, f"{folder}/{t.name}", "native", t.kind, t.tool)
                     for t in session_plan(p))
    from tactilepipe.tool.formats.trials import list_trials
    out = []
    for name, path, fmt in list_trials(folder):
        kind, tool = _trial_kind_and_tool(folder, Path(path), fmt)
        out.append(Recording(STUDY, session, name, str(path), fmt, kind, str(tool)))
    return tuple(out)


def _trial_kind_and_tool(session_dir: str, path: Path, fmt: str) -> tuple[str, str]:
    """(kind, tool) of a recorded trial, from its own metadata (native meta.json, a ROS bag's
    sidecar) or, in the public layout, its kind folder and the session's trials.csv."""
    if fmt == "native":
        from tactilepipe.tool.formats.native_layout import TrialMeta
        meta = TrialMeta.read(path)
        return meta.kind, meta.tool
    if fmt == "public":
        from tactilepipe.tool.formats.trials import public_trial_meta, read_trials_csv
        meta = public_trial_meta(read_trials_csv(session_dir), path)
        return ("normal" if "data_normal" in str(path) else "shear"), meta["tool"]
    from tactilepipe.tool.formats.rosbag import read_sidecar_meta
    meta = read_sidecar_meta(path)
    return meta["kind"], meta["tool"]


def ingest_inputs(recording: Recording, folder: str) -> list[str]:
    """A simulated trial's meta.json stands for its folder (the simulator writes it whole); a real
    one's files are those reading it opens."""
    if is_simulated(recording.session):
        return [f"{folder}/{CALIBRATION}", f"{recording.path}/meta.json"]
    return files_on_disk(recording, folder)


def files_on_disk(recording: Recording, folder: str) -> list[str]:
    from tactilepipe.tool.formats.trials import trial_files
    return trial_files(recording.path, recording.format, folder)


def simulated_files(recordings: tuple[Recording, ...], folder: str) -> list[str]:
    return [f for r in recordings for f in ingest_inputs(r, folder)]


# --- training runs: a job each, with a stamp of its own (pipeline/stamp_keeper.py) ----------------
RUN_STAGE = "tool-train"


def run_definition(p: dict, run: str) -> dict:
    from tactilepipe.tool import runs
    return runs.run_definition(p, run)


def run_source_keys(p: dict, run: str) -> tuple[str, ...]:
    from tactilepipe.tool import runs
    return runs.run_source_keys(p["tool_train"], run)


# --- the compute estimate of `snakemake -n` (pipeline/estimate.py): tool/estimate.py ---------------
MEASURED_RULES = ("tool_train",)


def measured_seconds(p: dict, rule: str, wildcards: dict, runtimes) -> float | None:
    from tactilepipe.tool.estimate import measured_seconds
    return measured_seconds(p, rule, wildcards, runtimes)


def modelled_report(p: dict, jobs: list, run_spec, build_dir) -> list[str]:
    """The training runs' modelled FLOPs and hours (counting them imports torch: only when planned)."""
    if not any(j[0] == "tool_train" for j in jobs):
        return []
    from tactilepipe.tool.estimate import modelled_report
    return modelled_report(p, jobs, run_spec, build_dir)


# --- trials by kind, over every session ------------------------------------------------------------
def trials(sheet, kind: str) -> list[Recording]:
    """The trials of one force kind, over every tool session of ``sheet`` (pipeline/sessions.py)."""
    return [r for s in sheet.sessions(STUDY) for r in sheet.recordings(STUDY, s) if r.kind == kind]


def trial_inputs(sheet, kind: str) -> list[str]:
    """The files the ingest jobs of one kind's trials read."""
    return [f for r in trials(sheet, kind) for f in sheet.ingest_inputs(r)]


def tools(sheet, kind: str) -> list[str]:
    """The tools of a kind's trials (the leave-one-tool-out runs leave each out in turn)."""
    return sorted({r.tool for r in trials(sheet, kind)})


# --- what each scene ends in ---------------------------------------------------------------------
def metric_rows(p: dict) -> list[str]:
    """A row per model variant."""
    return list(p["tool_train"]["variants"])


def split_names(scene: str, p: dict, sheet) -> list[str]:
    """Every split file of a tool scene: each repeat of the drawn splits, one per held-out tool, lopo."""
    from tactilepipe.tool.data.splits import split_name
    return [split_name(k, r) for k in ("frame", "trial") for r in range(p["tool_split"]["repeats"])] + \
        [f"loto_{t}" for t in tools(sheet, scene_label(scene))] + ["lopo"]


def data_targets(scene: str, results: str, p: dict, sheet) -> list[str]:
    """QC report, clock figures, data figures and every split of a tool scene (no model)."""
    return [f"{results}/{scene}/qc.md"] + \
        figure_files(f"{results}/tool/qc", [f"{s}_clock_sync" for s in sheet.sessions(STUDY)], PLOT_DATA) + \
        figure_files(f"{results}/{scene}/figures", DATA_FIGURES, PLOT_DATA) + \
        [f"{results}/{scene}/splits/{x}.json" for x in split_names(scene, p, sheet)]


def model_targets(scene: str, results: str, p: dict) -> list[str]:
    """Metrics, tables and figures of every trained model run of a tool scene."""
    return report_files(scene, results, metric_rows(p),
                        [f"{f}.json" for f in ("scores", "provenance", "runtime")] +
                        [f"tables/{t}.md" for t in model_tables(p)] + figures("figures", model_figures(p)))


def targets(scene: str, results: str, p: dict, sheet, data_only: bool = False) -> list[str]:
    return data_targets(scene, results, p, sheet) + ([] if data_only else model_targets(scene, results, p))


def caption_stem(stem: str, p: dict) -> str:
    """A table named like a figure (intervals, per_tool, loto) has its own caption."""
    return f"{stem}_table" if stem in model_figures(p) else stem
