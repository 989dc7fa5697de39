"""The Arduino that samples the Nano17, read over its serial port into a trial's force.log.

The firmware's contract (docs/rig.md): 115200 baud, 8 data bits, no parity, 1 stop bit; after a
reset it prints one line per sample, ``<millis>,<a0>,<a1>,<a2>,<a3>,<a4>,<a5>`` ending in ``\\n``
(``\\r\\n`` is accepted), the Arduino's own millisecond clock and the six gauge channels as 10-bit
ADC counts. Opening the port resets an Arduino (DTR), so its clock starts a fraction of a second
after the open; ``# start_host_ns`` is the host time (ns since 1970) taken the moment the port
opened, and ingest refines the offset from the data (tool/data/clock_sync.py).

Every line is written to force.log as received, so the log is the Arduino's output byte for
byte and ingest's parser (tool/formats/serial_log.py) decides what to keep. The reader counts the
lines that parser would drop, by reason, for the trial's meta.json and the progress line.
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field
from typing import BinaryIO

import numpy as np

from tactilepipe.core.errors import InputError
from tactilepipe.rig.reader import DeviceReader
from tactilepipe.tool.formats.native_layout import calibrate
from tactilepipe.tool.formats.serial_log import parse_line

BAUD = 115200
READ_TIMEOUT_S = 0.2                 # the port's read timeout: how often the reader checks for stop
SILENT_AFTER_S = 1.0                 # no line for this long (15 Hz expected) counts as a stall


@dataclass
class SerialStats:
    lines: int = 0
    samples: int = 0
    bad_lines: Counter = field(default_factory=Counter)
    stalls: int = 0
    lost: str = ""
    start_host_ns: int = 0
    first_counts: np.ndarray | None = None       # the zero-force bias of the progress line's force
    last_counts: np.ndarray | None = None

    def as_dict(self) -> dict:
        return {"lines": self.lines, "samples": self.samples, "unparsed_lines": dict(self.bad_lines),
                "stalls": self.stalls, "lost": self.lost, "start_host_ns": self.start_host_ns}


class ArduinoReader(DeviceReader):
    """Opens ``port`` (stamping ``# start_host_ns``), then copies its lines to ``log`` on a thread."""

    def __init__(self, port: str, log: BinaryIO, baud: int = BAUD):
        import serial                                   # pyserial: only the recorder needs it
        self._serial_error = serial.SerialException
        try:
            self._port = serial.Serial(port, baud, timeout=READ_TIMEOUT_S)
        except (serial.SerialException, ValueError) as exc:
            raise InputError(port, f"cannot open the Arduino's serial port: {exc}") from None
        self.stats = SerialStats(start_host_ns=time.time_ns())
        self._log = log
        self._log.write(f"# start_host_ns={self.stats.start_host_ns}\n".encode())
        self.port = port
        self._init_thread("arduino")

    def _close(self) -> None:
        self._port.close()

    def force(self, matrix: np.ndarray) -> np.ndarray | None:
        """The last sample's (Fx, Fy, Fz) in N against the trial's first sample (a trial starts
        without contact), for the progress line; None before the first sample."""
        if self.stats.last_counts is None:
            return None
        return calibrate(self.stats.last_counts[None], matrix, self.stats.first_counts)[0, :3]

    def _run(self) -> None:
        last = time.monotonic()
        pending = b""
        while not self._stop.is_set():
            try:
                chunk = self._port.readline()
            except (self._serial_error, OSError) as exc:
                self.stats.lost = f"serial port closed ({exc})"
                break
            now = time.monotonic()
            if not chunk:
                if now - last > SILENT_AFTER_S:
                    self.stats.stalls += 1
                    last = now
                continue
            last = now
            pending += chunk
            if not pending.endswith(b"\n"):
                continue                                  # a partial line: the rest follows
            self._take(pending)
            pending = b""
        if pending:                                       # a line cut by the stop or the unplug
            self._take(pending)

    def _take(self, line: bytes) -> None:
        self._log.write(line)
        self.stats.lines += 1
        text = line.decode("ascii", errors="replace").removesuffix("\n").removesuffix("\r")
        parsed = parse_line(text)
        if isinstance(parsed, str):
            self.stats.bad_lines[parsed] += 1
        else:
            self.stats.samples += 1
            self.stats.last_counts = np.asarray(parsed[1])
            if self.stats.first_counts is None:
                self.stats.first_counts = self.stats.last_counts
