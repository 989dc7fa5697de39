"""What the workflow knows of a study, in the study's own words: the vocabulary of its contract.

Each study package declares its contract in its ``contract.py`` (volume/, drift/, tool/); the one
module that lists the studies is tactilepipe/studies.py. The workflow's library (pipeline/) reads
a study only through these names, so adding a study, a scene or an output touches that study's
package, not pipeline/. A contract module defines:

- ``STUDY``: its folder under raw/ (raw/<study>/<session>/) and the sessions key of params.yaml;
- ``SIMULATOR``: the stage that writes a simulated session (``sim-<scale>``), and ``SIMULATED_MARK``,
  the file of such a session that DVC's stage of the simulator asks Snakemake for;
- ``DVC_STAGES``: {DVC stage: Snakemake targets} of its scenes (workflow/scripts/dvc_yaml.py), in
  order: a job belongs to the first stage whose targets need it (a study's data before its models);
- ``SCENES``: {scene: Scene}, the scenes it builds and the stages that make their numbers;
- ``PLOT_DATA``: the figures written with their data beside them (<figure>.csv), drawn by DVC;
- ``REPORT_LABELS``: what `snakemake --report` calls each item (by file stem);
- ``sessions(p)``, ``recordings(p, folder, session)``, ``ingest_inputs(recording, folder)``,
  ``files_on_disk(recording, folder)``, ``simulated_files(recordings, folder)``: its session reader;
- ``metric_rows(p)``: its rows of DVC's metrics (core/metric_rows.py), the same in each scene;
- ``targets(scene, results, p, sheet, data_only)``: every file a scene ends in (a scene made by one
  report stage, as volume's and drift's: ``report_outputs(scene, results, p)``, what it writes);
- ``caption_stem(stem, p)``: the caption file of a report item whose stem names two items;
- ``scores``: how `tactilepipe diff` reads its scenes' scores.json (its scores_layout.py: the
  scored series, the draws two runs share, earlier layouts, the stages that leave the draws alone);
- its part of the compute estimate a dry run prints (pipeline/estimate.py): ``MEASURED_RULES``
  (rules whose jobs the last build timed), ``measured_seconds(p, rule, wildcards, runtimes)`` and
  ``modelled_report(p, jobs, run_spec, build_dir)`` (lines; [] for none);
- a study with training jobs of their own: ``RUN_STAGE``, ``run_definition(p, run)``,
  ``run_source_keys(p, run)`` (each run's parameter stamp, pipeline/stamp_keeper.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tactilepipe.core.metric_rows import metric_files


@dataclass(frozen=True)
class Recording:
    study: str          # volume | drift | tool: the folder raw/<study>/
    session: str
    name: str           # the bag's stem or the trial's name: names its shard
    path: str           # the bag, or the trial's folder or bag
    format: str         # bag (PapillArray) | native | public | ros (tool trials)
    kind: str = ""      # a tool trial's force: normal | shear
    tool: str = ""      # a tool trial's tool


@dataclass(frozen=True)
class Scene:
    study: str                  # the study whose sessions it reads (raw/<study>/) and its simulator
    stages: tuple[str, ...]     # the stages that make its numbers, recordings to report


def figure_files(folder: str, names, plot_data=()) -> list[str]:
    """Every file a figure is written as: PNG, its SVG twin (core/atomic.py save_figure) and, for
    the figures of ``plot_data``, its data."""
    return [f"{folder}/{n}{ext}" for n in names
            for ext in (".png", ".svg") + ((".csv",) if n in plot_data else ())]


def report_files(scene: str, results: str, rows, outputs) -> list[str]:
    """A scene's metric rows (core/metric_rows.py) and its other ``outputs`` (paths under the
    scene's folder), under results/<build>/<scene>/."""
    return [f"{results}/{scene}/{f}" for f in metric_files(rows) + list(outputs)]


# --- the plain answers, for a study with nothing more to say -----------------------------------------
def recording_file(recording: Recording, folder: str) -> list[str]:
    """A recording that is one file (a PapillArray bag): reading it opens that file alone."""
    return [recording.path]


def same_stem(stem: str, p: dict) -> str:
    """Each report item's caption is named by its own file's stem."""
    return stem


def nothing_measured(p: dict, rule: str, wildcards: dict, runtimes) -> float | None:
    return None


def nothing_modelled(p: dict, jobs: list, run_spec, build_dir) -> list[str]:
    return []


# --- a scene's scores as `tactilepipe diff` reads them (each study's contract says where they are) --
def score_number(x) -> float:
    """A score as a float: null (json's None) is NaN, so it can never pass as a number."""
    return math.nan if x is None else float(x)


def same_value(a, b) -> bool:
    """Equal, or both NaN."""
    return a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))
