"""Result tables, written as CSV and Markdown side by side."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.atomic import write_text


def write_table(table: pd.DataFrame, stem: Path, title: str, floatfmt: str = "{:.4f}") -> None:
    """The table as CSV (for machines) and Markdown with a bold title (for papers and READMEs)."""
    write_text(stem.with_suffix(".csv"), table.to_csv(index=False))
    cols = list(table.columns)
    lines = [f"**{title}**", "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for row in table.itertuples(index=False):
        cells = [floatfmt.format(v) if isinstance(v, (float, np.floating)) else str(v) for v in row]
        lines.append("| " + " | ".join(cells) + " |")
    write_text(stem.with_suffix(".md"), "\n".join(lines) + "\n")
