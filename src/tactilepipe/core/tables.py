"""Result tables, written as CSV, Markdown and HTML side by side."""

from __future__ import annotations

import html
import math
import re
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
                nan_text: str = UNDEFINED, machine_only: tuple[str, ...] = ()) -> None:
    """The table as CSV (for machines), Markdown with a bold title (for papers and READMEs) and an
    HTML table (for the Snakemake report, which shows HTML as a page and Markdown only as a download).

    ``machine_only`` columns (e.g. a mean already shown as "mean ± std" text) go to the CSV only, so
    a reader sees each number once. A NaN or missing value (e.g. an R² of constant targets) reads
    ``nan_text`` ("undefined") in the Markdown and HTML and is an empty cell in the CSV; infinities
    stay "inf"."""
    unknown = [c for c in machine_only if c not in table.columns]
    if unknown:
        raise ValueError(f"{stem.name}: machine_only names columns the table lacks: {unknown}")
    write_text(stem.with_suffix(".csv"), table.to_csv(index=False))
    shown = table.drop(columns=list(machine_only))
    cols = [str(c) for c in shown.columns]
    cells = [[_cell(v, floatfmt, nan_text) for v in row] for row in shown.itertuples(index=False)]
    lines = [f"**{title}**", "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(row) + " |" for row in cells]
    write_text(stem.with_suffix(".md"), "\n".join(lines) + "\n")
    write_text(stem.with_suffix(".html"), html_table(title, cols, cells))


def html_table(title: str, columns: list[str], rows: list[list[str]]) -> str:
    """A self-contained HTML table: numbers right-aligned, the title as its caption."""
    esc = html.escape
    numeric = re.compile(r"^[-+−]?(\d|inf|nan)")
    head = "".join(f"<th>{esc(c)}</th>" for c in columns)
    body = "\n".join("<tr>" + "".join(
        f'<td class="num">{esc(v)}</td>' if numeric.match(v) else f"<td>{esc(v)}</td>" for v in row) + "</tr>"
        for row in rows)
    return (f"<style>{TABLE_CSS}</style>\n<table class=\"tactilepipe\">\n<caption>{esc(title)}</caption>\n"
            f"<thead><tr>{head}</tr></thead>\n<tbody>\n{body}\n</tbody>\n</table>\n")


def markdown_html(text: str) -> str:
    """HTML of the Markdown this project writes: '#' headings, paragraphs and pipe tables (a
    table's first row is its header, its second the alignment row)."""
    out, table = [], []

    def flush():
        if table:
            rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in table]
            page = html_table("", rows[0], rows[2:])
            out.append(page.replace("<caption></caption>\n", "").split("</style>\n", 1)[1])
            table.clear()

    for line in text.splitlines():
        if line.lstrip().startswith("|"):
            table.append(line)
            continue
        flush()
        if line.startswith("#"):
            level = min(len(line) - len(line.lstrip("#")) + 2, 6)
            out.append(f"<h{level}>{html.escape(line.lstrip('#').strip())}</h{level}>")
        elif line.strip():
            out.append(f"<p>{html.escape(line.strip())}</p>")
    flush()
    return f"<style>{TABLE_CSS}</style>\n" + "\n".join(out) + "\n"


TABLE_CSS = ("table.tactilepipe{border-collapse:collapse;font:13px/1.4 sans-serif;margin:0.5em 0}"
             "table.tactilepipe caption{text-align:left;font-weight:bold;padding:0.3em 0}"
             "table.tactilepipe th,table.tactilepipe td{border-bottom:1px solid #ddd;padding:2px 8px;text-align:left}"
             "table.tactilepipe td.num{text-align:right;font-variant-numeric:tabular-nums}"
             "table.tactilepipe thead th{border-bottom:2px solid #888}")
