"""Study 001, section 3: thermal drift of a PapillArray sensor (simulate, analyse, figures).

A session is two runs of 5-s recordings taken every few minutes after the driver's bias request:
"unloaded" (nothing on the sensor) and "loaded" (a known weight placed on the sensor for each
recording). Recordings are named ``<run>_t<MM>`` (MM = minutes since the bias), both as bags and
as their Parquet shards; the analysis takes run and time from that name only.

What the analysis needs to know about the session itself (the reference weight put on the sensor
in the loaded run) comes from ``session.json`` beside the bags, which a rig writes as it records
and the simulator writes too, so a real session is never analysed with simulator settings.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from tactilepipe.core.errors import InputError
from tactilepipe.core.rawfile import META_MAX, read_raw_text

RUNS = ("unloaded", "loaded")
RECORDING_SUFFIXES = (".bag", ".parquet")
_NAME = re.compile(r"^(?P<run>unloaded|loaded)_t(?P<minutes>\d{2,})$")


def recording_name(run: str, t_min: int) -> str:
    return f"{run}_t{int(t_min):02d}"


def parse_recording_name(path: str | Path) -> tuple[str, int]:
    """(run, minutes since bias) from ``<run>_t<MM>.bag|.parquet``; InputError naming the file otherwise."""
    path = Path(path)
    match = _NAME.match(path.stem) if path.suffix in RECORDING_SUFFIXES or path.suffix == "" else None
    if match is None:
        raise InputError(path, "drift recording names must look like <run>_t<MM>.bag or .parquet "
                               f"with run one of {'|'.join(RUNS)} (e.g. loaded_t05.parquet)")
    return match["run"], int(match["minutes"])


SESSION_META = "session.json"


def read_session_meta(path: str | Path) -> dict:
    """{"reference_load_g": g} of a drift session's ``session.json``; InputError naming the file
    and the problem when it is missing, unreadable or the weight is not a number >= 0."""
    path = Path(path)
    try:
        meta = json.loads(read_raw_text(path, META_MAX, "session.json", encoding="utf-8-sig"))
    except FileNotFoundError:
        raise InputError(path, 'missing: a drift session states its reference weight here, e.g. '
                               '{"reference_load_g": 500}') from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(path, f"not valid JSON: {exc}") from None
    load = meta.get("reference_load_g") if isinstance(meta, dict) else None
    if isinstance(load, bool) or not isinstance(load, (int, float)) or not load >= 0:
        raise InputError(path, f"'reference_load_g' must be a weight in grams >= 0, got {load!r}")
    return {"reference_load_g": float(load)}
