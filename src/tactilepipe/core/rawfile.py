"""Raw recording files read within a size bound.

A reader that takes a whole file into memory trusts its size: a recording replaced by a link to
/dev/zero (or a FIFO, or a folder) would be read until the memory runs out, and a file far larger
than any recording stands for a mistake (a disk image copied into the session, a log left running
for a week). Every whole-file read of a raw recording goes through ``read_raw_bytes``: a path that
is not a regular file, or a file over its kind's bound, is one InputError naming it, and no more
than bound + 1 bytes are ever read (a file that grows while it is read is caught too). Files
read in a stream (bags) are checked with ``check_raw_file`` before they are opened.

The bounds are far above any real recording of their kind, so none is ever refused; below them
the readers' own checks name what is wrong with the contents.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from tactilepipe.core.errors import InputError

MB = 1 << 20
GB = 1 << 30

# force.log: an Arduino line ("ms,adc,adc,adc,adc,adc,adc") is about 40 bytes; at 1 kHz a minute is
# 2.4 MB and 64 MB is about half an hour, while a trial lasts seconds to minutes.
FORCE_LOG_MAX = 64 * MB
# one camera frame, PNG or JPEG: a DIGIT frame (320 x 240) is 50-250 kB, even a 4K PNG is under 50 MB.
IMAGE_MAX = 64 * MB
# a CSV table of a session or sensor (frames.csv, lifts.csv, trials.csv, a public force file): a row
# per frame or lift of some 40 bytes; an hour of frames at 60 fps is under 10 MB.
TABLE_MAX = 64 * MB
# small JSON or XML a person or rig writes (meta.json, session.json, a bag's sidecar, nano17.cal):
# a few hundred bytes to a few kB.
META_MAX = 1 * MB
# a ROS bag, read message by message: a minute of two uncompressed 320 x 240 camera streams at
# 60 fps is under 2 GB; a volume lift's PapillArray bag is a few MB.
BAG_MAX = 16 * GB

_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISSOCK, "a socket"))


def _size_text(n: int) -> str:
    return f"{n / GB:.1f} GB" if n >= GB else f"{n / MB:.1f} MB" if n >= MB else f"{n} bytes"


def check_raw_file(path: str | Path, limit: int, what: str) -> int:
    """The size of the regular file at ``path`` (following links); InputError naming it when it is
    not a regular file or holds more than ``limit`` bytes. A missing file raises FileNotFoundError,
    for the caller to say what the file is for."""
    st = os.stat(path)
    if not stat.S_ISREG(st.st_mode):
        kind = next((name for test, name in _KINDS if test(st.st_mode)), "not a regular file")
        raise InputError(path, f"{kind}, not a file: a {what} is a regular file; not read")
    size = st.st_size
    if size > limit:
        raise InputError(path, f"{_size_text(size)}: larger than any {what} ({_size_text(limit)} at most); not read")
    return size


def read_raw_bytes(path: str | Path, limit: int, what: str) -> bytes:
    """The bytes of the regular file at ``path``, at most ``limit`` of them (``check_raw_file``)."""
    check_raw_file(path, limit, what)
    with open(path, "rb") as f:
        data = f.read(limit + 1)
    if len(data) > limit:                          # it grew after the check
        raise InputError(path, f"more than {_size_text(limit)}: larger than any {what}; not read")
    return data


def read_raw_text(path: str | Path, limit: int, what: str, encoding: str = "utf-8") -> str:
    """``read_raw_bytes`` decoded (UnicodeDecodeError as from ``Path.read_text``)."""
    return read_raw_bytes(path, limit, what).decode(encoding)
