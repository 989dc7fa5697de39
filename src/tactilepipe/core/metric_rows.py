"""DVC's metrics as rows: a scene writes one small JSON file per model, input or run under
``metrics/``, each with the same few keys (a tool model's ``mae``, ``rmse``, ``r2``; a volume
input's ``r2``; a drift run's drift and recalibration interval).

`dvc metrics show` prints a row per file and a column per key. One file per scene with a key per
model and score made a column of every pair (24 columns, 461 characters wide); one file per model
makes a column per score, and the table fits a terminal. Every other number of a scene is in its
``scores.json``.
"""

from __future__ import annotations

from pathlib import Path

from tactilepipe.core.atomic import write_json

FOLDER = "metrics"


def metric_files(rows) -> list[str]:
    """The files of ``rows`` (names of models, inputs or runs), relative to the scene's folder."""
    return [f"{FOLDER}/{row}.json" for row in rows]


def write_metric_rows(scene_dir: str | Path, rows: dict[str, dict]) -> None:
    """Write each row's values to ``scene_dir/metrics/<row>.json``, and remove the rows of a model
    no longer built (DVC declares the folder, so a row left behind would still be shown)."""
    folder = Path(scene_dir) / FOLDER
    for row, values in rows.items():
        write_json(folder / f"{row}.json", values)
    for stale in set(folder.glob("*.json")) - {folder / f"{row}.json" for row in rows}:
        stale.unlink()
