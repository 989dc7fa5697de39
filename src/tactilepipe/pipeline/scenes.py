"""The scenes a build makes, in one table: for each, the study whose sessions it reads, the stages
that make its numbers, and the files it ends in (its targets). The workflow's target lists and
provenance records, the dvc.yaml generator and `tactilepipe diff` all read this table.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from tactilepipe.core.errors import ConfigError
from tactilepipe.core.metric_rows import FOLDER as METRICS_FOLDER
from tactilepipe.core.metric_rows import metric_files
from tactilepipe.core.simulated import is_simulated
from tactilepipe.drift import RUNS as DRIFT_RUNS
from tactilepipe.pipeline.sessions import SessionSheet
from tactilepipe.tool.scenes import TOOL_SCENES, scene_label


@dataclass(frozen=True)
class Scene:
    study: str                  # volume | drift | tool: raw/<study>/ and its simulator
    stages: tuple[str, ...]     # the stages that make its numbers, recordings to report


SIMULATOR = {"volume": "volume-simulate", "drift": "drift-simulate", "tool": "tool-simulate"}
_TOOL_STAGES = ("tool-ingest", "tool-dataset", "tool-split", "tool-train", "tool-model-report")
SCENES: dict[str, Scene] = {
    "volume": Scene("volume", ("papillarray-ingest", "volume-dataset", "volume-split", "volume-train",
                               "volume-gridsearch", "volume-baseline", "volume-report")),
    "drift": Scene("drift", ("papillarray-ingest", "drift-report")),
    **{name: Scene("tool", _TOOL_STAGES) for name in TOOL_SCENES},
}

# The figures whose numbers are also written as a table beside them (<figure>.csv), declared as
# DVC data plots (dvc.yaml `plots:`), so `dvc plots diff` draws two revisions on one axis.
PLOT_DATA = {"volume": ["mu_r2_curve"], "drift": ["drift_curves"], "tool": ["error_vs_runtime", "intervals"]}


def figure_files(folder: str, names, study: str) -> list[str]:
    """Every file a figure is written as: PNG, its SVG twin (core/atomic.py save_figure) and, for
    the figures of PLOT_DATA, its data."""
    return [f"{folder}/{n}{ext}" for n in names
            for ext in (".png", ".svg") + ((".csv",) if n in PLOT_DATA[study] else ())]


def metric_rows(name: str, p: dict) -> list[str]:
    """A scene's rows of DVC's metrics (core/metric_rows.py): a tool scene's variants, the volume
    scene's force inputs and its baseline, the drift scene's runs. ``name`` may be the rules'
    "{scene}" wildcard of the tool scenes."""
    study = "tool" if name == "{scene}" else scene(name).study
    if study == "tool":
        return list(p["tool_train"]["variants"])
    if study == "volume":
        return [*p["mlp"]["modalities"], "baseline"]
    return list(DRIFT_RUNS)


def metric_outputs(folder: str, name: str, p: dict) -> list[str]:
    """The files of a scene's metric rows under its ``folder``."""
    return [f"{folder}/{f}" for f in metric_files(metric_rows(name, p))]


# what each scene ends in, under results/<build>/<scene>/ (the report stages write these names), and
# its metric rows (metric_rows)
VOLUME_OUTPUTS = ["scores.json", "provenance.json", "runtime.json"] + \
    [f"tables/{t}.md" for t in ("table1_r2", "table2_volumes", "unseen_volumes", "runtime", "grid_search")] + \
    figure_files("figures", ("r2_by_modality", "mu_r2_curve", "true_vs_estimated", "error_vs_runtime",
                             "pillar_map"), "volume")
DRIFT_OUTPUTS = ["scores.json", "provenance.json", "fits.md"] + figure_files("figures", ["drift_curves"], "drift")
TOOL_DATA_FIGURES = ["force_histogram", "force_profiles", "rmse_vs_force", "pressing_strip"]


def tool_model_figures(p: dict) -> list[str]:
    return ["sorted_predictions", "over_time", "per_tool", "window_heatmap", "regression", "error_vs_runtime",
            "intervals"] + (["loto"] if p["tool_train"]["loto"] else [])


def tool_model_tables(p: dict) -> list[str]:
    return ["variants", "intervals", "differences", "paper_orderings", "per_tool", "per_window", "runtime"] + \
        (["loto"] if p["tool_train"]["loto"] else [])


def scene(name: str) -> Scene:
    if name not in SCENES:
        raise ConfigError(f"scene '{name}' is not built by this workflow (available: {', '.join(SCENES)})")
    return SCENES[name]


def provenance_stages(name: str, sheet: SessionSheet, simulator: str = "if simulated") -> tuple[list[str], list[str]]:
    """The stages that make a scene's numbers (its simulator's first when a session is simulated,
    or with simulator="always") and the scene's raw session folders."""
    s = scene(name)
    sessions = sheet.sessions(s.study)
    simulated = simulator == "always" or any(is_simulated(x) for x in sessions)
    return ([SIMULATOR[s.study]] if simulated else []) + list(s.stages), [sheet.folder(s.study, x) for x in sessions]


def tool_split_names(name: str, p: dict, sheet: SessionSheet) -> list[str]:
    """Every split file of a tool scene: each repeat of the drawn splits, one per held-out tool, lopo."""
    from tactilepipe.tool.data.splits import split_name
    return [split_name(k, r) for k in ("frame", "trial") for r in range(p["tool_split"]["repeats"])] + \
        [f"loto_{t}" for t in sheet.tools(scene_label(name))] + ["lopo"]


def tool_data_targets(name: str, results: str, p: dict, sheet: SessionSheet) -> list[str]:
    """QC report, clock figures, data figures and every split of a tool scene (no model)."""
    return [f"{results}/{name}/qc.md"] + \
        figure_files(f"{results}/tool/qc", [f"{s}_clock_sync" for s in sheet.sessions("tool")], "tool") + \
        figure_files(f"{results}/{name}/figures", TOOL_DATA_FIGURES, "tool") + \
        [f"{results}/{name}/splits/{x}.json" for x in tool_split_names(name, p, sheet)]


def tool_model_targets(name: str, results: str, p: dict) -> list[str]:
    """Metrics, tables and figures of every trained model run of a tool scene."""
    return metric_outputs(f"{results}/{name}", name, p) + \
        [f"{results}/{name}/{f}.json" for f in ("scores", "provenance", "runtime")] + \
        [f"{results}/{name}/tables/{t}.md" for t in tool_model_tables(p)] + \
        figure_files(f"{results}/{name}/figures", tool_model_figures(p), "tool")


def scene_targets(names, results: str, p: dict, sheet: SessionSheet, data_only: bool = False) -> list[str]:
    """Every file the scenes' hand-written rules end in (``data_only``: a tool scene's data stages'
    only); the stages that declare their rules add theirs (stage_rules.declared_outputs)."""
    out = []
    for name in names:
        study = scene(name).study
        if study == "tool":
            out += tool_data_targets(name, results, p, sheet) + ([] if data_only else tool_model_targets(name, results, p))
        else:
            out += report_outputs(name, results, p)
    return out


def report_outputs(name: str, results: str, p: dict) -> list[str]:
    """What the report stage of the volume or drift scene writes."""
    return metric_outputs(f"{results}/{name}", name, p) + \
        [f"{results}/{name}/{f}" for f in {"volume": VOLUME_OUTPUTS, "drift": DRIFT_OUTPUTS}[name]]


# What the report's result tables call each item (workflow/report/<group>/<caption>.rst), in place
# of its file name; a tool scene's items share the tool labels (the category names the scene).
REPORT_LABELS = {
    "volume": {"table1_r2": "Table 1: R² of each force input and the baseline",
               "table2_volumes": "Table 2: estimated volume per true volume",
               "unseen_volumes": "Volumes never seen in training", "runtime": "Fit and prediction time per method",
               "grid_search": "MLP grid search", "r2_by_modality": "R² of each force input and the baseline",
               "mu_r2_curve": "Baseline R² against the friction coefficient μ",
               "true_vs_estimated": "True against estimated volume", "error_vs_runtime": "R² against run time",
               "pillar_map": "Per-pillar forces during a hold"},
    "drift": {"fits": "Drift fits and recalibration interval",
              "drift_curves": "Drift with the fitted curves"},
    "tool": {"qc": "Quality control of the data stages",
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
             "loto_table": "Leave one tool out: error per held-out tool"},
}


def report_items(files, scene_name: str, p: dict) -> list[tuple[str, str | None, str | None, dict | None]]:
    """(file, caption, subcategory, labels) of each output, for `snakemake --report`: caption None
    for an output that is not a report item (provenance, run times, scores.json; a Markdown table, whose HTML
    twin is the item: the report shows HTML as a page, Markdown only as a download). ``scene_name``
    may be the rules' "{scene}" wildcard: tool scenes share the tool captions (workflow/report/tool/)."""
    group = scene_name if scene_name in ("volume", "drift") else "tool"
    out = []
    for f in files:
        path = Path(f)
        # a figure's vector twin and data: files beside the report's PNG item, not items of their own;
        # DVC's metric rows: their numbers are in the report's tables
        if path.name in ("provenance.json", "runtime.json", "scores.json") or path.parent.name == METRICS_FOLDER or \
                (path.parent.name == "figures" and path.suffix in (".svg", ".csv")):
            out.append((f, None, None, None))
            continue
        if path.suffix == ".md" and path.name != "qc.md":
            out.append((f, None, None, None))
            f, path = str(path.with_suffix(".html")), path.with_suffix(".html")
        kind = "figures" if path.suffix == ".png" else "tables"
        # a tool table named like a figure has its own caption
        stem = f"{path.stem}_table" if group == "tool" and path.suffix == ".html" and \
            path.stem in tool_model_figures(p) else path.stem
        out.append((f, f"../report/{group}/{stem}.rst", kind, {"result": REPORT_LABELS[group][stem]}))
    return out
