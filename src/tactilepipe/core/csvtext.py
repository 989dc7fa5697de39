"""Text of the small CSV files people write by hand or in a spreadsheet (lifts.csv, trials.csv,
frames.csv): UTF-8, with or without the byte-order mark spreadsheets put first."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.core.errors import InputError
from tactilepipe.core.rawfile import TABLE_MAX, read_raw_bytes


def read_text_table(path: str | Path, what: str) -> str:
    path = Path(path)
    raw = read_raw_bytes(path, TABLE_MAX, what)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise InputError(path, f"not UTF-8 text (byte 0x{exc.object[exc.start]:02x}): not a {what}",
                         f"line {line}") from None
