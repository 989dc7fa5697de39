"""`tactilepipe record`: trials in the rig's layout, from two DIGITs and the Arduino of the Nano17.

One trial: the serial port is opened first (its open time is force.log's ``# start_host_ns``),
then both cameras; every frame is written as a PNG with its host time in frames.csv, every serial
line into force.log as received and its arrival time into force_arrival.csv; after ``seconds``
the devices are closed and meta.json is written. The layout is in tool/formats/native_layout.py
and docs/rig.md.

The trial is written in a staging folder beside the sessions (``<root>/.recording/<session>/``)
and renamed into the session only when complete, so the session never holds half a trial. A trial
that stops half-way (a camera or the port lost, Ctrl-C, an error) is moved to
``<root>/incomplete/<session>/<trial>/`` with the reason in its meta.json, and the command says so.
Dropped frames, read timeouts and unparsable serial lines are counted into meta.json
(``notes.recorder``).
"""

from __future__ import annotations

import os
import queue
import re
import shutil
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from tactilepipe.core.atomic import write_text
from tactilepipe.core.errors import ArgumentError, InputError, TactilepipeError
from tactilepipe.rig.arduino import BAUD, ArduinoReader
from tactilepipe.tool.formats.arrival_log import ARRIVAL_NAME
from tactilepipe.rig.cameras import MODES, Camera
from tactilepipe.rig.reader import STOP_TIMEOUT_S
from tactilepipe.tool.formats.native_layout import (FRAME_NAME, SENSORS, TrialMeta, check_tool_name,
                                                    read_calibration)

STAGING, INCOMPLETE = ".recording", "incomplete"
PROGRESS_EVERY_S = 0.5
FIRST_SAMPLE_TIMEOUT_S = 3.0          # an Arduino boots in well under a second after the port's reset
# a trial's or session's folder name: one plain name, never a path (no separator, no "..")
PLAIN_NAME = re.compile(r"^[A-Za-z0-9_.-]+$")


class TrialIncomplete(TactilepipeError):
    """A trial stopped half-way; it was set aside, not added to the session."""


@dataclass(frozen=True)
class Devices:
    left: str                        # camera sources (device, DIGIT serial number, or file)
    right: str
    port: str                        # the Arduino's serial port
    mode: str = "qvga60"
    baud: int = BAUD


class _FrameWriter:
    """PNG encoding and writing off the camera threads (a slow disk must not stall a capture)."""

    def __init__(self, trial_dir: Path):
        self.dir = trial_dir
        self.stamps = {s: [] for s in SENSORS}
        self._queue: queue.Queue = queue.Queue(maxsize=600)
        self._thread = threading.Thread(target=self._run, name="frame-writer", daemon=True)
        self.error: BaseException | None = None
        self._thread.start()

    def put(self, sensor: str, index: int, host_ns: int, frame: np.ndarray) -> None:
        self.stamps[sensor].append(host_ns)
        self._queue.put((sensor, index, frame))

    def close(self) -> None:
        self._queue.put(None)
        self._thread.join()
        if self.error is not None:
            raise self.error

    def _run(self) -> None:
        while (item := self._queue.get()) is not None:
            if self.error is not None:
                continue
            sensor, index, frame = item
            try:
                if not cv2.imwrite(str(self.dir / sensor / FRAME_NAME.format(index)), frame):
                    raise InputError(self.dir / sensor, f"cannot write frame {index}")
            except BaseException as exc:              # noqa: BLE001 - handed to the recording thread
                self.error = exc


def install_calibration(session_dir: Path, calibration: Path | None) -> None:
    """The session's nano17.cal: copied from ``calibration`` (checked against physics) when the
    session has none; an existing one must be the same file."""
    target = session_dir / "nano17.cal"
    if calibration is None:
        if not target.exists():
            raise ArgumentError(f"{session_dir} has no nano17.cal: give the Nano17's calibration file with "
                                f"--calibration (ATI's .cal for your sensor's serial number)")
        read_calibration(target)
        return
    read_calibration(calibration)
    if target.exists():
        if target.read_bytes() != Path(calibration).read_bytes():
            raise ArgumentError(f"{target} exists and differs from {calibration}: one session has one Nano17 "
                                f"calibration; start a new session for another sensor")
        return
    write_text(target, Path(calibration).read_text())


def check_plain_name(name: str, what: str) -> None:
    """Refuse a trial or session name that is not one plain folder name: a separator or a ".."
    would put the trial outside its session (``--trial ../../x``)."""
    if not PLAIN_NAME.match(name) or ".." in name or name.startswith("."):
        raise ArgumentError(f"{what} {name!r}: a name is letters, digits, _ - and . (not first), with no path "
                            f"separator and no '..'")


def check_session_path(session: Path) -> None:
    """A session is a folder whose own name is plain, reached without '..' (the staging and
    incomplete folders are made beside it, by its name)."""
    if ".." in session.parts:
        raise ArgumentError(f"--session {session}: give the session's folder without '..'")
    check_plain_name(session.name, "--session folder name")


def next_trial_name(session_dir: Path, stem: str) -> str:
    taken = {p.name for p in session_dir.iterdir()} if session_dir.exists() else set()
    k = 0
    while f"{stem}_{k:03d}" in taken:
        k += 1
    return f"{stem}_{k:03d}"


def record_trial(session_dir: str | Path, meta: TrialMeta, devices: Devices, seconds: float,
                 out=sys.stderr) -> Path:
    """Record one trial into ``session_dir``/``meta.trial``; returns its folder. Raises
    TrialIncomplete (after setting the trial aside) when it stops half-way."""
    session_dir = Path(session_dir)
    check_tool_name(meta.tool, "--tool")
    check_session_path(session_dir)
    check_plain_name(meta.trial, "--trial")
    final = session_dir / meta.trial
    if final.exists():
        raise ArgumentError(f"trial {final} exists already: choose another name")
    staging = session_dir.parent / STAGING / session_dir.name / meta.trial
    if staging.exists():                    # left by a recorder that was killed: keep it, aside
        _set_aside(staging, session_dir, meta, "the recorder was killed while recording it")
    for sensor in SENSORS:
        (staging / sensor).mkdir(parents=True)
    writer = _FrameWriter(staging)
    cameras, reader, reason, setup_error = [], None, "", None
    log = open(staging / "force.log", "wb")
    arrival = open(staging / ARRIVAL_NAME, "wb")
    try:
        reader = ArduinoReader(devices.port, log, devices.baud, arrival).start()
        _first_sample(reader)           # the Arduino is up: every frame will lie within the force log
        for sensor, source in zip(SENSORS, (devices.left, devices.right)):
            cameras.append(Camera(sensor, source, devices.mode,
                                  lambda i, t, f, s=sensor: writer.put(s, i, t, f)))
        for camera in cameras:
            camera.start()
        reason = _watch(cameras, reader, read_calibration(session_dir / "nano17.cal"), seconds, out)
    except KeyboardInterrupt:
        reason = "stopped by the user (Ctrl-C)"
    except TactilepipeError as exc:
        if not any(c.running or c.stats.frames for c in cameras):
            setup_error = exc               # a device that would not open: nothing was recorded
        reason = str(exc)
    finally:
        camera_stats = {c.name: c.stop().as_dict() for c in cameras}
        serial_stats = reader.stop().as_dict() if reader is not None else {}
        stuck = [f"camera {c.name}" for c in cameras if c.stuck] + (["the Arduino's port"] if reader and reader.stuck
                                                                    else [])
        if stuck:                           # its thread may still write into the trial: set it aside
            reason = (f"{reason}; " if reason else "") + f"the reader thread of {' and '.join(stuck)} did not stop " \
                                                         f"within {STOP_TIMEOUT_S:g} s (left behind)"
        log.close()
        arrival.close()
        try:
            writer.close()
        except BaseException as exc:                # noqa: BLE001 - the trial is set aside, with why
            reason = reason or f"writing frames failed: {exc}"
    if setup_error is not None:
        shutil.rmtree(staging)
        raise setup_error
    for sensor in SENSORS:
        stamps = writer.stamps[sensor]
        write_text(staging / sensor / "frames.csv",
                   "frame,host_ns\n" + "".join(f"{i},{t}\n" for i, t in enumerate(stamps)))
    duration = _duration_s(writer.stamps)
    samples = serial_stats.get("samples", 0)
    reason = reason or serial_stats.get("reset", "")      # a reset after the last progress check
    if not reason and (not samples or min(len(s) for s in writer.stamps.values()) < 2):
        reason = f"too little was recorded ({samples} serial samples, frames " \
                 f"{ {s: len(v) for s, v in writer.stamps.items()} })"
    notes = dict(meta.notes)
    notes["recorder"] = {"cameras": camera_stats, "serial": serial_stats, "mode": devices.mode,
                         "sources": {"digit_left": devices.left, "digit_right": devices.right,
                                     "serial_port": devices.port, "baud": devices.baud},
                         "seconds_asked": seconds, "seconds_recorded": round(duration, 3)}
    done = TrialMeta(**{**meta.__dict__, "camera_fps": float(MODES[devices.mode][2]),
                        "serial_hz": round(samples / duration, 3) if duration > 0 and samples > 1 else meta.serial_hz,
                        "notes": notes})
    if reason:
        where = _set_aside(staging, session_dir, done, reason)
        raise TrialIncomplete(f"trial {meta.trial} stopped half-way ({reason}); set aside in {where}, "
                              f"not added to {session_dir}")
    done.write(staging)
    session_dir.mkdir(parents=True, exist_ok=True)
    os.rename(staging, final)               # the trial appears in the session whole, or not at all
    return final


def _first_sample(reader: ArduinoReader) -> None:
    deadline = time.monotonic() + FIRST_SAMPLE_TIMEOUT_S
    while reader.stats.samples == 0:
        if not reader.running:
            raise InputError(reader.port, f"the port stopped before the first sample: {reader.stats.lost}")
        if time.monotonic() > deadline:
            raise InputError(reader.port, f"no sample line within {FIRST_SAMPLE_TIMEOUT_S:g} s of opening the port "
                                          f"({reader.stats.lines} lines, unparsable: {dict(reader.stats.bad_lines)}): "
                                          f"the wrong port or baud rate, or firmware that does not print the "
                                          f"documented lines (docs/rig.md)")
        time.sleep(0.005)


def _watch(cameras: list[Camera], reader: ArduinoReader, matrix: np.ndarray, seconds: float, out) -> str:
    """Wait out the trial, printing a progress line; the reason it stopped early, or ''."""
    start = time.monotonic()
    last_print = 0.0
    while (elapsed := time.monotonic() - start) < seconds:
        for c in cameras:
            if not c.running:
                return f"camera {c.name} ({c.source}) stopped: {c.stats.lost or 'its thread ended'}"
        if not reader.running:
            return f"the Arduino's port stopped: {reader.stats.lost or 'its thread ended'}"
        if reader.stats.reset:
            return reader.stats.reset
        if elapsed - last_print >= PROGRESS_EVERY_S:
            last_print = elapsed
            print("\r" + progress_line(cameras, reader, matrix, elapsed, seconds), end="", file=out, flush=True)
        time.sleep(0.02)
    print("\r" + progress_line(cameras, reader, matrix, seconds, seconds), file=out, flush=True)
    return ""


def progress_line(cameras: list[Camera], reader: ArduinoReader, matrix: np.ndarray, elapsed: float,
                  seconds: float) -> str:
    fps = " | ".join(f"{c.name} {c.stats.fps:5.1f} fps" for c in cameras)
    drops = sum(c.stats.dropped for c in cameras)
    timeouts = sum(c.stats.timeouts for c in cameras)
    f = reader.force(matrix)
    force = "F -" if f is None else f"|F| {np.linalg.norm(f):5.2f} N (Fz {f[2]:+6.2f})"
    return (f"{elapsed:5.1f}/{seconds:g} s | {fps} | {force} | dropped frames {drops}, timeouts {timeouts}, "
            f"bad serial lines {sum(reader.stats.bad_lines.values())}")


def _duration_s(stamps: dict[str, list[int]]) -> float:
    spans = [(s[-1] - s[0]) / 1e9 for s in stamps.values() if len(s) > 1]
    return min(spans) if spans else 0.0


def _set_aside(staging: Path, session_dir: Path, meta: TrialMeta, reason: str) -> Path:
    aside = session_dir.parent / INCOMPLETE / session_dir.name / meta.trial
    k = 1
    while aside.exists():
        aside = aside.with_name(f"{meta.trial}.{k}")
        k += 1
    notes = {**meta.notes, "incomplete": reason}
    try:
        TrialMeta(**{**meta.__dict__, "notes": notes}).write(staging)
    except OSError:
        pass                                # the reason is in the message either way
    aside.parent.mkdir(parents=True, exist_ok=True)
    shutil.move(str(staging), str(aside))
    return aside
