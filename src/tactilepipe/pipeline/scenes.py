"""The scenes a build makes, in one table: for each, the study whose sessions it reads, the stages
that make its numbers, and the files it ends in (its targets). The workflow's target lists and
provenance records, the dvc.yaml generator and `tactilepipe diff` all read this table.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from tactilepipe.core.errors import ConfigError
from tactilepipe.pipeline.sessions import SessionSheet, is_simulated
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

# what each scene ends in, under results/<build>/<scene>/ (the report stages write these names)
VOLUME_OUTPUTS = ["metrics.json", "scores.json", "provenance.json", "runtime.json"] + \
    [f"tables/{t}.md" for t in ("table1_r2", "table2_volumes", "unseen_volumes", "runtime", "grid_search")] + \
    [f"figures/{f}.png" for f in ("r2_by_modality", "mu_r2_curve", "true_vs_estimated", "error_vs_runtime",
                                  "pillar_map")]
DRIFT_OUTPUTS = ["metrics.json", "scores.json", "provenance.json", "fits.md", "figures/drift_curves.png"]
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
    return [f"{results}/{name}/qc.md"] + [f"{results}/tool/qc/{s}_clock_sync.png" for s in sheet.sessions("tool")] + \
        [f"{results}/{name}/figures/{f}.png" for f in TOOL_DATA_FIGURES] + \
        [f"{results}/{name}/splits/{x}.json" for x in tool_split_names(name, p, sheet)]


def tool_model_targets(name: str, results: str, p: dict) -> list[str]:
    """Metrics, tables and figures of every trained model run of a tool scene."""
    return [f"{results}/{name}/{f}.json" for f in ("metrics", "scores", "provenance", "runtime")] + \
        [f"{results}/{name}/tables/{t}.md" for t in tool_model_tables(p)] + \
        [f"{results}/{name}/figures/{f}.png" for f in tool_model_figures(p)]


def scene_targets(names, results: str, p: dict, sheet: SessionSheet, data_only: bool = False) -> list[str]:
    """Every file the scenes' hand-written rules end in (``data_only``: a tool scene's data stages'
    only); the stages that declare their rules add theirs (stage_rules.declared_outputs)."""
    out = []
    for name in names:
        study = scene(name).study
        if study == "tool":
            out += tool_data_targets(name, results, p, sheet) + ([] if data_only else tool_model_targets(name, results, p))
        else:
            out += report_outputs(name, results)
    return out


def report_outputs(name: str, results: str) -> list[str]:
    """What the report stage of the volume or drift scene writes."""
    return [f"{results}/{name}/{f}" for f in {"volume": VOLUME_OUTPUTS, "drift": DRIFT_OUTPUTS}[name]]


def report_items(files, scene_name: str, p: dict) -> list[tuple[str, str | None, str | None]]:
    """(file, caption, subcategory) of each output, for `snakemake --report`: caption None for an
    output that is not a report item (provenance, run times, scores.json; a Markdown table, whose HTML twin is
    the item: the report shows HTML as a page, Markdown only as a download). ``scene_name`` may be
    the rules' "{scene}" wildcard: tool scenes share the tool captions (workflow/report/tool/)."""
    group = scene_name if scene_name in ("volume", "drift") else "tool"
    out = []
    for f in files:
        path = Path(f)
        if path.name in ("provenance.json", "runtime.json", "scores.json"):
            out.append((f, None, None))
            continue
        if path.suffix == ".md" and path.name != "qc.md":
            out.append((f, None, None))
            f, path = str(path.with_suffix(".html")), path.with_suffix(".html")
        kind = {".png": "figures", ".json": "metrics"}.get(path.suffix, "tables")
        # a tool table named like a figure has its own caption
        stem = f"{path.stem}_table" if group == "tool" and path.suffix == ".html" and \
            path.stem in tool_model_figures(p) else path.stem
        out.append((f, f"../report/{group}/{stem}.rst", kind))
    return out
