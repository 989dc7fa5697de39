"""Atomic output writing: write to a temporary sibling, then rename over the target.

An interrupted run therefore leaves either the old file or no file, never half of one,
and a re-run completes. A temporary left by a killed process (SIGKILL, power loss) is removed
the next time the same target is written. A write that fails for lack of space or permission
(full disk, read-only folder, file size limit) raises OutputError naming the target, after
removing the temporary.
"""

from __future__ import annotations

import contextlib
import errno
import glob
import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterator

from tactilepipe.core.errors import TactilepipeError

# errors of the place written to, not of the data: reported as "cannot write <target>"
OUTPUT_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG}


class OutputError(TactilepipeError):
    """An output cannot be written (full disk, read-only or forbidden folder, size limit)."""

    def __init__(self, path: str | Path, problem: str):
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


def _errno_of(exc: BaseException) -> int | None:
    """errno of an OSError, also when a library (pyarrow, numpy) only kept it in the message."""
    if getattr(exc, "errno", None):
        return exc.errno
    text = str(exc)
    for code in OUTPUT_ERRNOS:
        if os.strerror(code) in text:
            return code
    return None


def output_error(target: str | Path, exc: OSError, tmp: str | Path | None = None,
                 setting_up: bool = False) -> OutputError | None:
    """OutputError for ``exc`` if it is a full disk / permission / size-limit error in writing
    ``target`` (or its temporary ``tmp``), else None. While the body of ``atomic_path`` runs, an
    error naming another file is about that file (an input, or another output), not this one."""
    filename = getattr(exc, "filename", None)
    if not setting_up and filename is not None and Path(filename) not in {Path(target), Path(tmp or target)}:
        return None
    code = _errno_of(exc)
    if code not in OUTPUT_ERRNOS:
        return None
    return OutputError(target, f"cannot write: {os.strerror(code)} (nothing was written)")


def remove_stale_temporaries(target: str | Path) -> None:
    """Remove temporaries of ``target`` left by a killed writer (``.<name>.*.tmp``, files or folders).

    Only one job writes a given target at a time (Snakemake gives every output to one job), so
    any such sibling that exists before a write starts is debris of an earlier, killed write.
    """
    target = Path(target)
    for stale in glob.glob(os.path.join(glob.escape(str(target.parent)), f".{glob.escape(target.name)}.*.tmp")):
        if os.path.isdir(stale) and not os.path.islink(stale):
            shutil.rmtree(stale, ignore_errors=True)
        else:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(stale)


@contextlib.contextmanager
def atomic_path(target: str | Path) -> Iterator[Path]:
    """Yield a temporary path next to ``target``; rename it onto ``target`` on success."""
    target = Path(target)
    tmp_path = None
    setting_up = True
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        remove_stale_temporaries(target)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
        os.close(fd)
        tmp_path = Path(tmp)
        # mkstemp makes the file 0600; give it the mode an ordinary open() would (shared lab storage)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        setting_up = False
        yield tmp_path
        os.replace(tmp_path, target)
    except OSError as exc:
        err = output_error(target, exc, tmp_path, setting_up)
        if err is None:
            raise
        raise err from exc
    finally:
        if tmp_path is not None and tmp_path.exists():
            tmp_path.unlink()


def write_text(target: str | Path, text: str) -> None:
    with atomic_path(target) as tmp:
        tmp.write_text(text)


def write_json(target: str | Path, obj) -> None:
    write_text(target, json.dumps(obj, indent=2, sort_keys=True) + "\n")


def write_parquet(target: str | Path, frame) -> None:
    with atomic_path(target) as tmp:
        frame.to_parquet(tmp, index=False)


# the vector twin of every PNG figure: for papers (scales without blur) and for diffs (text)
VECTOR_SUFFIX = ".svg"
# matplotlib's SVG writer names clip paths and glyphs with ids hashed from a random salt and stamps
# a date: a fixed salt and no date make two writes of one figure the same bytes
SVG_RC = {"svg.hashsalt": "tactilepipe", "svg.fonttype": "path"}


def vector_twin(png: str | Path) -> Path:
    """Where the vector copy of a PNG figure is written (beside it, same stem)."""
    return Path(png).with_suffix(VECTOR_SUFFIX)


def save_figure(target: str | Path, fig, dpi: int = 150) -> None:
    """Write ``fig`` to ``target``; a PNG also gets its SVG twin (``vector_twin``), byte-identical
    from one run to the next."""
    import matplotlib

    fmt = Path(target).suffix.lstrip(".") or "png"
    with atomic_path(target) as tmp:
        fig.savefig(tmp, dpi=dpi, bbox_inches="tight", format=fmt)
    if fmt == "png":
        with atomic_path(vector_twin(target)) as tmp, matplotlib.rc_context(SVG_RC):
            fig.savefig(tmp, bbox_inches="tight", format="svg", metadata={"Date": None})


def open_memmap(path: str | Path, shape: tuple, dtype):
    """A new .npy file mapped for writing (``np.lib.format.open_memmap(path, "w+")``), with its
    disk blocks reserved first.

    A memory map writes pages lazily: without the reservation a full disk shows up as SIGBUS
    (the process dies, no message, its temporary left behind) instead of an OSError here.
    """
    import numpy as np
    arr = np.lib.format.open_memmap(path, "w+", dtype, shape)
    with open(path, "r+b") as fh:
        try:
            os.posix_fallocate(fh.fileno(), 0, os.fstat(fh.fileno()).st_size)
        except OSError as exc:
            if exc.errno not in (errno.EOPNOTSUPP, errno.EINVAL, errno.ENOSYS):
                del arr
                raise OSError(exc.errno, exc.strerror, str(path)) from None
    return arr
