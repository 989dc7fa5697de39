"""Result tables, written as CSV and Markdown side by side."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.core.atomic import write_text
from tactilepipe.core.metrics import UNDEFINED


def _cell(value, floatfmt: str, nan_text: str) -> str:
    if value is None:
        return nan_text
    if isinstance(value, (float, np.floating)):
        return nan_text if math.isnan(value) else floatfmt.format(value)
    return str(value)


def write_table(table: pd.DataFrame, stem: Path, title: str, floatfmt: str = "{:.4f}",
                nan_text: str = UNDEFINED) -> None:
    """The table as CSV (for machines) and Markdown with a bold title (for papers and READMEs).

    A NaN or missing value (e.g. an R² of constant targets) reads ``nan_text`` ("undefined") in
    the Markdown and is an empty cell in the CSV; infinities stay "inf"."""
    write_text(stem.with_suffix(".csv"), table.to_csv(index=False))
    cols = list(table.columns)
    lines = [f"**{title}**", "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for row in table.itertuples(index=False):
        lines.append("| " + " | ".join(_cell(v, floatfmt, nan_text) for v in row) + " |")
    write_text(stem.with_suffix(".md"), "\n".join(lines) + "\n")
