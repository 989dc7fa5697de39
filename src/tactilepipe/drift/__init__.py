"""Study 001, section 3: thermal drift of a PapillArray sensor (simulate, analyse, figures).

A session is two runs of 5-s recordings taken every few minutes after the driver's bias request:
"unloaded" (nothing on the sensor) and "loaded" (a known weight placed on the sensor for each
recording). Recordings are named ``<run>_t<MM>`` (MM = minutes since the bias), both as bags and
as their Parquet shards; the analysis takes run and time from that name only.
"""

from __future__ import annotations

import re
from pathlib import Path

from tactilepipe.errors import InputError

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
