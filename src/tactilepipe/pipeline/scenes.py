"""The scenes a build makes, in one table: for each, the study whose sessions it reads, the stages
that make its numbers, and the files it ends in (its targets). Each study declares its own scenes
and their files (its contract.py, core/study.py); this gathers them for the workflow's target
lists and provenance records, the dvc.yaml generator and `tactilepipe diff`.
"""

from __future__ import annotations

from pathlib import Path

from tactilepipe.core.errors import ConfigError
from tactilepipe.core.metric_rows import FOLDER as METRICS_FOLDER
from tactilepipe.core.metric_rows import metric_files
from tactilepipe.core.simulated import is_simulated
from tactilepipe.core.study import Scene
from tactilepipe.pipeline import stage_rules
from tactilepipe.pipeline.sessions import SessionSheet
from tactilepipe.studies import contracts

CONTRACTS = contracts()
SCENES: dict[str, Scene] = {name: s for c in CONTRACTS.values() for name, s in c.SCENES.items()}


def scene(name: str) -> Scene:
    if name not in SCENES:
        raise ConfigError(f"scene '{name}' is not built by this workflow (available: {', '.join(SCENES)})")
    return SCENES[name]


def study_of(name: str) -> str:
    """The study of a scene, or a study's own name (a rule's "{scene}" stands for any of its scenes)."""
    return name if name in CONTRACTS else scene(name).study


def contract(name: str):
    """The contract (core/study.py) of a scene's study, or of the study ``name``."""
    return CONTRACTS[study_of(name)]


def metric_outputs(folder: str, name: str, p: dict) -> list[str]:
    """The files of a scene's rows of DVC's metrics (core/metric_rows.py) under its ``folder``;
    ``name``: the scene, or its study's name."""
    return [f"{folder}/{f}" for f in metric_files(contract(name).metric_rows(p))]


def provenance_stages(name: str, sheet: SessionSheet, simulator: str = "if simulated") -> tuple[list[str], list[str]]:
    """The stages that make a scene's numbers (its simulator's first when a session is simulated,
    or with simulator="always"; then its study's list, then any other stage that declares its rule
    in the scene) and the scene's raw session folders."""
    s = scene(name)
    sessions = sheet.sessions(s.study)
    simulated = simulator == "always" or any(is_simulated(x) for x in sessions)
    declared = [r.stage for r in stage_rules.stage_rules([name]) if r.stage not in s.stages]
    return ([contract(name).SIMULATOR] if simulated else []) + list(s.stages) + declared, \
        [sheet.folder(s.study, x) for x in sessions]


def scene_targets(names, results: str, p: dict, sheet: SessionSheet, data_only: bool = False) -> list[str]:
    """Every file the scenes' hand-written rules end in (``data_only``: a tool scene's data stages'
    only); the stages that declare their rules add theirs (stage_rules.declared_outputs)."""
    return [f for name in names for f in contract(name).targets(name, results, p, sheet, data_only)]


def report_outputs(name: str, results: str, p: dict) -> list[str]:
    """What the report stage of a scene with one report (volume, drift) writes."""
    return contract(name).report_outputs(name, results, p)


def report_items(files, scene_name: str, p: dict) -> list[tuple[str, str | None, str | None, dict | None]]:
    """(file, caption, subcategory, labels) of each output, for `snakemake --report`: caption None
    for an output that is not a report item (provenance, run times, scores.json; a Markdown table, whose HTML
    twin is the item: the report shows HTML as a page, Markdown only as a download). ``scene_name``
    may be a study's name, for the rules' "{scene}" wildcard: a study's scenes share its captions
    (workflow/report/<study>/) and its labels (REPORT_LABELS of its contract)."""
    group, study = study_of(scene_name), contract(scene_name)
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
        stem = study.caption_stem(path.stem, p) if path.suffix == ".html" else path.stem
        out.append((f, f"../report/{group}/{stem}.rst", kind, {"result": study.REPORT_LABELS[stem]}))
    return out
