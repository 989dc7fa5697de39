"""The Arduino that samples the Nano17, read over its serial port into a trial's force.log.

The firmware's contract (docs/rig.md): 115200 baud, 8 data bits, no parity, 1 stop bit; after a
reset it prints one line per sample, ``<millis>,<a0>,<a1>,<a2>,<a3>,<a4>,<a5>`` ending in ``\\n``
(``\\r\\n`` and a lone ``\\r`` are accepted), the Arduino's own millisecond clock and the six gauge
channels as 10-bit ADC counts. Opening the port resets an Arduino (DTR), so its clock starts a
fraction of a second after the open; ``# start_host_ns`` is the host time (ns since 1970) taken the moment the port
opened, and ingest refines the offset from the data (tool/data/clock_sync.py).

Every line is written to force.log as received, so the log is the Arduino's output byte for
byte and ingest's parser (tool/formats/serial_log.py) decides what to keep; the one exception is
a line that ends in a lone ``\\r``, which gets a ``\\n`` after it, so that the log has lines for the
parser. Each read waits at most READ_TIMEOUT_S and takes what has arrived (never "until a line
end", which a board that ends lines otherwise would never send), and a run of MAX_LINE_BYTES
with no line end is cut off as a line of its own, so the reader never waits on the device nor
grows without bound. The reader counts the line ends it saw, and the lines that parser would
drop, by reason, for the trial's meta.json and the progress line.
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field
from typing import BinaryIO

import numpy as np

from tactilepipe.core.errors import InputError
from tactilepipe.rig.reader import DeviceReader
from tactilepipe.rig.settings import BAUD
from tactilepipe.tool.formats.native_layout import calibrate
from tactilepipe.tool.formats.serial_log import parse_line

READ_TIMEOUT_S = 0.2                 # the port's read timeout: how often the reader checks for stop
SILENT_AFTER_S = 1.0                 # no line for this long (15 Hz expected) counts as a stall
MAX_LINE_BYTES = 1024                # a sample line is under 40 bytes: longer is not the firmware's output


@dataclass
class SerialStats:
    lines: int = 0
    samples: int = 0
    bad_lines: Counter = field(default_factory=Counter)
    stalls: int = 0
    line_ends: Counter = field(default_factory=Counter)     # "\\n", "\\r\\n", "\\r", "none (cut at N bytes)"
    lost: str = ""
    start_host_ns: int = 0
    first_counts: np.ndarray | None = None       # the zero-force bias of the progress line's force
    last_counts: np.ndarray | None = None
    last_ms: int | None = None                   # the Arduino clock of the last sample
    reset: str = ""                              # how the clock jumped back (a reset mid-trial), if it did

    def as_dict(self) -> dict:
        return {"lines": self.lines, "samples": self.samples, "unparsed_lines": dict(self.bad_lines),
                "line_ends": dict(self.line_ends), "stalls": self.stalls, "lost": self.lost,
                "reset": self.reset, "start_host_ns": self.start_host_ns}


class ArduinoReader(DeviceReader):
    """Opens ``port`` (stamping ``# start_host_ns``), then copies its lines to ``log`` on a thread."""

    def __init__(self, port: str, log: BinaryIO, baud: int = BAUD, arrival: BinaryIO | None = None):
        import serial                                   # pyserial: only the recorder needs it
        self._serial_error = serial.SerialException
        try:
            self._port = serial.Serial(port, baud, timeout=READ_TIMEOUT_S)
        except (serial.SerialException, ValueError) as exc:
            raise InputError(port, f"cannot open the Arduino's serial port: {exc}") from None
        self.stats = SerialStats(start_host_ns=time.time_ns())
        self._log = log
        self._log.write(f"# start_host_ns={self.stats.start_host_ns}\n".encode())
        # each line's arrival on the host clock, by its force.log line number: the Arduino's clock is
        # fitted to these (tool/formats/arrival_log.py), the port-open time is only a coarse start
        self._arrival, self._arrived_ns = arrival, 0
        if arrival is not None:
            arrival.write(b"line,host_ns\n")
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
                # what has arrived, or one byte within the port's timeout: never "until a line end"
                # (pyserial's readline waits for a \n as long as bytes keep coming)
                chunk = self._port.read(max(1, self._port.in_waiting))
            except (self._serial_error, OSError, TypeError) as exc:      # TypeError: closed under it
                self.stats.lost = f"serial port closed ({exc})"
                break
            now = time.monotonic()
            if chunk:
                last = now
                self._arrived_ns = time.time_ns()
            elif now - last > SILENT_AFTER_S:
                self.stats.stalls += 1
                last = now
            pending = self._lines(pending + chunk, quiet=not chunk)
        if pending:                                       # a line cut by the stop or the unplug
            self._take(pending, "")

    def _lines(self, data: bytes, quiet: bool) -> bytes:
        """Take every complete line of ``data``; return the rest. A line ends at \\n, \\r\\n or a
        lone \\r (one followed by anything but \\n, or by silence: a \\r\\n split across reads
        waits one read for its \\n)."""
        start = 0
        while True:
            cr, lf = data.find(b"\r", start), data.find(b"\n", start)
            if lf >= 0 and (cr < 0 or lf < cr):
                self._take(data[start:lf + 1], "\\n")
                start = lf + 1
            elif cr >= 0 and cr + 1 < len(data):
                if data[cr + 1:cr + 2] == b"\n":
                    self._take(data[start:cr + 2], "\\r\\n")
                    start = cr + 2
                else:
                    self._take(data[start:cr + 1] + b"\n", "\\r")
                    start = cr + 1
            elif cr >= 0 and quiet:                       # a \r last, and nothing followed it
                self._take(data[start:cr + 1] + b"\n", "\\r")
                start = cr + 1
            else:
                break
        rest = data[start:]
        if len(rest) > MAX_LINE_BYTES:                    # no line end in sight: not the firmware's output
            self._take(rest + b"\n", f"none (cut at {MAX_LINE_BYTES} bytes)")
            rest = b""
        return rest

    def _take(self, line: bytes, end: str) -> None:
        if end:
            self.stats.line_ends[end] += 1
        self._log.write(line)
        self.stats.lines += 1
        if self._arrival is not None:               # force.log's line 1 is the header
            self._arrival.write(f"{self.stats.lines + 1},{self._arrived_ns}\n".encode())
        text = line.decode("ascii", errors="replace").removesuffix("\n").removesuffix("\r")
        parsed = parse_line(text)
        if isinstance(parsed, str):
            self.stats.bad_lines[parsed] += 1
        else:
            self.stats.samples += 1
            ms = parsed[0]
            if self.stats.last_ms is not None and ms < self.stats.last_ms and not self.stats.reset:
                # the board restarted (a brown-out, a loose USB cable): its clock began again at 0,
                # and no one offset aligns the trial's two halves. Found here, the trial stops now.
                self.stats.reset = (f"the Arduino's clock jumped back from {self.stats.last_ms} to {ms} ms at "
                                    f"force.log line {self.stats.lines + 1}: it reset mid-trial")
            self.stats.last_ms = ms
            self.stats.last_counts = np.asarray(parsed[1])
            if self.stats.first_counts is None:
                self.stats.first_counts = self.stats.last_counts
