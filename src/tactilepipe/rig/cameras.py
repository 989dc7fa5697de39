"""The rig's two DIGIT cameras: found by serial number, opened through OpenCV, read on a thread each.

A DIGIT is a UVC camera. ``digit-interface`` finds one by the udev properties of its video node
(model DIGIT, the USB serial string as its serial number) and streams it through OpenCV; it is
not a dependency here because its release requires ``opencv-python``, which would install a
second ``cv2`` over the pinned headless build. The same facts are read from sysfs instead
(``list_digits``): the USB device above each ``/sys/class/video4linux/video*`` node carries the
product string, serial, manufacturer and release that udev copies into those properties, and
sysfs is there whether or not a udev daemon runs (containers).

Frames are stored the way ``digit-interface`` returns them: the sensor streams landscape
(320 x 240 or 640 x 480) and every frame is turned 90 degrees counter-clockwise into portrait
(``to_layout``), the orientation of the rig's layout (tool/formats/native_layout.py).

A source is a device (``/dev/video2``), a DIGIT's serial number (``D20262``), or a video file or
image sequence (``frames/frame_%06d.png``). A file is played at the stream mode's frame rate, one
frame per period as a camera would deliver it, so recording or estimating from a file exercises
the same code as from a device; only the source string differs.
"""

from __future__ import annotations

import re
import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from tactilepipe.core.errors import ArgumentError, InputError
from tactilepipe.rig.reader import DeviceReader
from tactilepipe.rig.settings import MODES

SYSFS_VIDEO = Path("/sys/class/video4linux")
DIGIT_PRODUCT = "DIGIT"
SERIAL_NUMBER = re.compile(r"D[0-9A-Z]{4,}")
READ_TIMEOUT_S = 1.0                 # a read that takes longer counts as a timeout
LOST_AFTER_TIMEOUTS = 3              # consecutive failed reads after which the camera counts as unplugged


@dataclass(frozen=True)
class DigitDevice:
    node: str                        # /dev/videoN
    serial: str
    manufacturer: str
    revision: str


def _read_attr(folder: Path, name: str) -> str:
    try:
        return (folder / name).read_text().strip()
    except OSError:
        return ""


def list_digits(sysfs_video: Path = SYSFS_VIDEO) -> list[DigitDevice]:
    """Every DIGIT plugged in, by its capture node (index 0; a UVC camera's second node carries
    metadata only), sorted by node."""
    found = []
    for entry in sorted(sysfs_video.glob("video*")):
        if _read_attr(entry, "index") not in ("", "0"):
            continue
        usb = (entry / "device").resolve()
        while usb != usb.parent and not (usb / "idVendor").exists():
            usb = usb.parent                # from the interface up to the USB device
        if _read_attr(usb, "product") != DIGIT_PRODUCT:
            continue
        found.append(DigitDevice(f"/dev/{entry.name}", _read_attr(usb, "serial"),
                                 _read_attr(usb, "manufacturer"), _read_attr(usb, "bcdDevice")))
    return found


def resolve_source(source: str, sysfs_video: Path = SYSFS_VIDEO) -> str:
    """The string OpenCV opens for ``source``: a DIGIT serial number becomes its video node."""
    if not SERIAL_NUMBER.fullmatch(source):
        return source
    digits = list_digits(sysfs_video)
    for d in digits:
        if d.serial == source:
            return d.node
    plugged = ", ".join(f"{d.serial} at {d.node}" for d in digits) or "none"
    raise ArgumentError(f"no DIGIT with serial number {source} is plugged in (DIGITs found: {plugged}); "
                        f"`tactilepipe record --list-digits` lists them")


def is_device(source: str) -> bool:
    return source.startswith("/dev/")


def to_layout(frame: np.ndarray) -> np.ndarray:
    """A frame as the sensor streams it (landscape) turned into the layout's portrait, as
    digit-interface turns it (transpose, then flip upside down)."""
    return cv2.rotate(frame, cv2.ROTATE_90_COUNTERCLOCKWISE)


def from_layout(frame: np.ndarray) -> np.ndarray:
    """The inverse of ``to_layout``: a stored frame as the sensor streamed it."""
    return cv2.rotate(frame, cv2.ROTATE_90_CLOCKWISE)


def open_capture(source: str, mode: str) -> cv2.VideoCapture:
    """An open VideoCapture at the DIGIT stream mode ``mode`` (a device is asked for it and must
    grant it; a file is checked against it)."""
    if mode not in MODES:
        raise ArgumentError(f"camera mode {mode!r}: choose one of {', '.join(MODES)}")
    width, height, fps = MODES[mode]
    if is_device(source):
        cap = cv2.VideoCapture(source, cv2.CAP_V4L2)
        if cap.isOpened():
            cap.set(cv2.CAP_PROP_FRAME_WIDTH, width)
            cap.set(cv2.CAP_PROP_FRAME_HEIGHT, height)
            cap.set(cv2.CAP_PROP_FPS, fps)
    else:
        if not ("%" in source or Path(source).is_file()):
            raise InputError(source, "no such camera source: give a /dev/video* node, a DIGIT serial number, "
                                     "a video file or an image sequence such as frame_%06d.png")
        cap = cv2.VideoCapture(source, cv2.CAP_IMAGES if "%" in source else cv2.CAP_ANY)
    if not cap.isOpened():
        raise InputError(source, "OpenCV cannot open this camera source (unplugged, in use by another program, "
                                 "or not a video)")
    got = (int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
    if is_device(source) and got != (width, height):
        cap.release()
        raise InputError(source, f"the camera streams {got[0]}x{got[1]}, not the {width}x{height} of mode "
                                 f"{mode}: is it a DIGIT?")
    return cap


@dataclass
class CameraStats:
    frames: int = 0
    dropped: int = 0                 # frames the sensor sent that never reached us (gaps in the stamps)
    late: int = 0                    # a file's frames read late (a gap in the stamps, no frame lost)
    timeouts: int = 0                # reads that failed or took longer than READ_TIMEOUT_S
    lost: str = ""                   # why the camera stopped delivering, if it did
    opened_host_ns: int = 0
    fps: float = 0.0                 # measured over the frames read

    def as_dict(self) -> dict:
        return {"frames": self.frames, "dropped_frames": self.dropped, "late_reads": self.late, "read_timeouts": self.timeouts,
                "lost": self.lost, "opened_host_ns": self.opened_host_ns, "measured_fps": round(self.fps, 3)}


@dataclass
class Camera(DeviceReader):
    """One camera read on its own thread: each frame, turned into the layout's orientation, is
    handed to ``on_frame(index, host_ns, frame)`` with the host time (ns since 1970) at which the
    read returned it. Gaps in those times longer than 1.5 periods are counted as dropped frames (as
    late reads for a file, which loses none)."""
    name: str
    source: str
    mode: str
    on_frame: callable
    stats: CameraStats = field(default_factory=CameraStats)

    def __post_init__(self):
        self._cap = open_capture(self.source, self.mode)
        self.stats.opened_host_ns = time.time_ns()
        self._init_thread(f"camera-{self.name}")

    @property
    def period_s(self) -> float:
        return 1.0 / MODES[self.mode][2]

    def _close(self) -> None:
        self._cap.release()

    def _run(self) -> None:
        period_ns = int(self.period_s * 1e9)
        paced = not is_device(self.source)
        start = time.monotonic_ns()
        last_ns, failures = None, 0
        while not self._stop.is_set():
            if paced:                                   # a file delivers at the mode's rate, like the sensor
                due = start + self.stats.frames * period_ns
                time.sleep(max(0, due - time.monotonic_ns()) / 1e9)
            t0 = time.monotonic()
            ok, frame = self._cap.read()
            host_ns = time.time_ns()
            if paced and not ok:
                self.stats.lost = "the file ended"
                return
            if not ok or frame is None or time.monotonic() - t0 > READ_TIMEOUT_S:
                self.stats.timeouts += 1
                failures += 1
                if failures >= LOST_AFTER_TIMEOUTS:
                    self.stats.lost = f"{failures} reads in a row failed or timed out (unplugged?)"
                    return
                if not ok:
                    continue
            failures = 0
            if last_ns is not None and host_ns - last_ns > 1.5 * period_ns:
                if paced:               # a file loses no frame: the gap is this thread's own delay
                    self.stats.late += 1
                else:
                    self.stats.dropped += int(round((host_ns - last_ns) / period_ns)) - 1
            last_ns = host_ns
            index = self.stats.frames
            self.stats.frames += 1
            if self.stats.frames > 1:
                self.stats.fps = (self.stats.frames - 1) / max((host_ns - self._first_ns) / 1e9, 1e-9)
            else:
                self._first_ns = host_ns
            self.on_frame(index, host_ns, to_layout(frame))
