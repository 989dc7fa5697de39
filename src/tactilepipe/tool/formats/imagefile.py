"""Reading one frame file: OpenCV decodes a truncated JPEG without complaint (the missing rows
come out grey), so a file must end where its format says it ends before it is decoded. A whole
file can still hold corrupt data: libjpeg and libpng then decode what they can and only print a
warning ("Corrupt JPEG data: ..."), which ``decode`` catches and turns into a refusal of the frame."""

from __future__ import annotations

import os
import sys
import tempfile
import threading
from pathlib import Path

import cv2
import numpy as np

from tactilepipe.core.errors import InputError
from tactilepipe.core.rawfile import IMAGE_MAX, read_raw_bytes

JPEG_START, JPEG_END = b"\xff\xd8", b"\xff\xd9"
PNG_START, PNG_END = b"\x89PNG\r\n\x1a\n", b"IEND"
# Some encoders pad a JPEG after its end marker; that much padding is still a whole image.
MAX_PADDING = 1024


def truncation(data: bytes) -> str | None:
    """Why ``data`` is not a whole JPEG or PNG (None when it is, or is another format)."""
    if data.startswith(JPEG_START):
        tail = data[-MAX_PADDING - 2:].rstrip(b"\x00")
        return None if tail.endswith(JPEG_END) else "truncated JPEG (no end-of-image marker)"
    if data.startswith(PNG_START):
        return None if PNG_END in data[-MAX_PADDING:] else "truncated PNG (no IEND chunk)"
    return None


def read_image(path: str | Path, flags: int = cv2.IMREAD_UNCHANGED, record: str | None = None) -> np.ndarray:
    """Decode one image file; InputError for a missing, unreadable or truncated one."""
    path = Path(path)
    try:
        data = read_raw_bytes(path, IMAGE_MAX, "camera frame")
    except FileNotFoundError:
        raise InputError(path, "unreadable or missing image (no such file)", record) from None
    problem = truncation(data)
    if problem:
        raise InputError(path, f"unreadable or missing image: {problem}", record)
    img, warning = decode(data, flags) if data else (None, "")
    if warning:
        raise InputError(path, f"corrupt image data: the decoder warned {warning!r}", record)
    if img is None:
        raise InputError(path, "unreadable or missing image (not a JPEG or PNG OpenCV can decode)", record)
    return img


# Decoder messages that say nothing about the pixels: padding before the end marker (UVC/MJPEG
# cameras write it), and a PNG's colour-profile chunk. OpenCV's own log lines start with "[".
BENIGN = ("extraneous bytes before marker 0xd9", "iCCP:")
_LOCK = threading.Lock()  # the C stderr is the process's: one decode at a time points it elsewhere
_SCRATCH: dict[int, object] = {}   # per process (a forked child must not share the parent's offset)


def decode(data: bytes | np.ndarray, flags: int) -> tuple[np.ndarray | None, str]:
    """``cv2.imdecode`` and the warnings the JPEG/PNG library printed while decoding (they go to
    the C stderr, which is pointed at a scratch file meanwhile), less the benign ones."""
    with _LOCK:
        scratch = _SCRATCH.get(os.getpid())
        if scratch is None:
            scratch = _SCRATCH[os.getpid()] = tempfile.TemporaryFile()
        scratch.seek(0)
        scratch.truncate()
        sys.stderr.flush()
        saved = os.dup(2)
        try:
            os.dup2(scratch.fileno(), 2)
            img = cv2.imdecode(np.frombuffer(data, np.uint8), flags)
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        scratch.seek(0)
        lines = scratch.read().decode(errors="replace").splitlines()
    warnings = [line.strip() for line in lines if line.strip() and not line.lstrip().startswith("[")
                and not any(b in line for b in BENIGN)]
    return img, "; ".join(warnings)
