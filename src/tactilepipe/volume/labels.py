"""lifts.csv: what the lab notes down for every bag of a volume session (bag,volume_ml,set).

Every row must name a bag in the session folder itself (shards are named after the bag's stem,
so `sub/x.bag` and `x.bag` would be one lift), once: a bag listed twice, with the same or a
conflicting volume, would enter the dataset twice and could land on both sides of a fold.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path, PurePosixPath

import numpy as np

from tactilepipe.core.csvtext import read_text_table
from tactilepipe.core.errors import InputError

HEADER = ("bag", "volume_ml", "set")


def _bag_name(path: Path, value: str, line: int) -> str:
    bag = PurePosixPath(value.strip().replace("\\", "/"))
    parts = [p for p in bag.parts if p != "."]
    if not value.strip() or len(parts) != 1 or bag.is_absolute() or parts[0] == "..":
        raise InputError(path, f"bag '{value}' must be a file name in the session folder (no sub-folder or "
                               f"absolute path: its shard is named after the stem alone)", f"line {line}")
    if not parts[0].endswith(".bag"):
        raise InputError(path, f"bag '{value}' must be a ROS1 .bag file", f"line {line}")
    return parts[0]


def read_session_labels(session_dir: str | Path) -> list[dict]:
    path = Path(session_dir) / "lifts.csv"
    if not path.exists():
        raise InputError(path, "missing: every recording session needs lifts.csv (bag,volume_ml,set)")
    reader = csv.DictReader(io.StringIO(read_text_table(path, "lifts.csv"), newline=""))
    fields = [f.strip() for f in reader.fieldnames or []]
    if not set(HEADER) <= set(fields):
        raise InputError(path, f"header must hold bag,volume_ml,set (found {reader.fieldnames})")
    reader.fieldnames = fields
    rows, seen = [], {}
    for line, row in enumerate(reader, start=2):
        if any(row.get(k) is None for k in HEADER):
            raise InputError(path, "too few fields (expected bag,volume_ml,set)", f"line {line}")
        bag = _bag_name(path, row["bag"], line)
        try:
            volume = float(row["volume_ml"])
        except (TypeError, ValueError):
            raise InputError(path, f"volume_ml '{row['volume_ml']}' is not a number", f"line {line}") from None
        if not np.isfinite(volume) or volume < 0:
            raise InputError(path, f"volume_ml {volume} must be finite and >= 0", f"line {line}")
        kind = row["set"].strip()
        if kind not in ("main", "unseen"):
            raise InputError(path, f"set '{row['set']}' must be main or unseen", f"line {line}")
        if bag in seen:
            first = rows[seen[bag]]
            same = first["volume_ml"] == volume and first["set"] == kind
            raise InputError(path, f"bag {bag} is listed again (first on line {first['line']}"
                                   f"{'' if same else ', with ' + str(first['volume_ml']) + ' ml, ' + first['set']}): "
                                   f"each bag is one lift", f"line {line}")
        seen[bag] = len(rows)
        rows.append({"bag": bag, "volume_ml": volume, "set": kind, "line": line})
    if not rows:
        raise InputError(path, "no lifts: the file holds only its header")
    return [{k: r[k] for k in HEADER} for r in rows]
