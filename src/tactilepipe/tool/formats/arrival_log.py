"""When each line of force.log reached the host, and the Arduino clock fitted from those times.

The recorder stamps every serial line on arrival (``force_arrival.csv`` beside force.log:
``line,host_ns``, the line number of force.log, 1-based as an editor counts, and the host clock in
ns). A line reaches the host some time after the Arduino stamped it: the gauges are read, the
line is sent at the baud rate, the USB adaptor polls, the operating system schedules the reader.
Each of these only ever adds delay, and most lines meet little of it; now and then one waits
tens of ms. So the Arduino's clock is the *lower envelope* of the points (arduino_ms, arrival):
a line through the least-delayed line of each stretch of the log. A late line, however late,
cannot move it; only the least-delayed lines do (the fit is as good as the fastest of a few
lines, about 0.2 ms with the USB adaptor's 1-ms polling). The envelope carries a constant delay
(reading, sending, the fastest USB transfer), to which the camera's own exposure-to-stamp
latency adds; both are taken out together, from the images of the whole session
(tool/data/session_clock.py).

Checks that need no images: the arrival stamps must cover the samples kept, increase, and the
Arduino's crystal must run within ``MAX_RATE_PPM`` of the host's clock (a log put beside another
trial's arrivals, or a line-number shift, shows as a rate or a scatter no rig has).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tactilepipe.core.errors import InputError

ARRIVAL_NAME = "force_arrival.csv"
MAX_RATE_PPM = 20000.0               # an Uno's ceramic resonator is within 0.5 %, a crystal within 100 ppm
ENVELOPE_BINS = 16                   # stretches of the log whose least-delayed lines the clock is fitted to
SAMPLES_PER_BIN = 8                  # at least this many lines each: one of 8 is rarely delayed much
MAX_TYPICAL_DELAY_MS = 20.0          # median delay above the envelope: more means the stamps are not of these lines
_INT = "0123456789"


@dataclass
class ArrivalFit:
    offset_ns: float                 # host ns at arduino_ms = 0 (on the envelope)
    ns_per_ms: float                 # host ns per Arduino ms (1e6 for a perfect crystal)
    median_delay_ms: float           # median delay of the lines above the envelope
    p95_delay_ms: float

    def host_ns(self, arduino_ms: np.ndarray) -> np.ndarray:
        return np.rint(self.offset_ns + self.ns_per_ms * np.asarray(arduino_ms, np.float64)).astype(np.int64)

    @property
    def rate_ppm(self) -> float:
        return (self.ns_per_ms / 1e6 - 1.0) * 1e6

    def record(self) -> dict:
        return {"rate_ppm": round(self.rate_ppm, 2), "median_delay_ms": round(self.median_delay_ms, 3),
                "p95_delay_ms": round(self.p95_delay_ms, 3)}


def read_arrivals(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(line numbers, host_ns) of force_arrival.csv: increasing line numbers, host_ns not decreasing."""
    path = Path(path)
    try:
        text = path.read_bytes().decode("ascii")
    except UnicodeDecodeError as exc:
        raise InputError(path, f"non-ASCII byte at offset {exc.start}: not an arrival log the recorder wrote") from None
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    if not lines or lines[0].strip() != "line,host_ns":
        raise InputError(path, "header must be 'line,host_ns'", "line 1")
    numbers, stamps = np.empty(len(lines) - 1, np.int64), np.empty(len(lines) - 1, np.int64)
    for i, row in enumerate(lines[1:]):
        parts = row.strip().split(",")
        if len(parts) != 2 or not all(p and p.strip(_INT) == "" and len(p) < 20 for p in parts):
            raise InputError(path, f"expected 'line,host_ns' integers, got {row!r}", f"line {i + 2}")
        numbers[i], stamps[i] = int(parts[0]), int(parts[1])
    if len(numbers) > 1 and (np.diff(numbers) <= 0).any():
        k = int(np.argmax(np.diff(numbers) <= 0)) + 1
        raise InputError(path, f"line numbers do not increase ({numbers[k - 1]} then {numbers[k]})", f"line {k + 2}")
    if len(stamps) > 1 and (np.diff(stamps) < 0).any():
        k = int(np.argmax(np.diff(stamps) < 0)) + 1
        raise InputError(path, "arrival stamps go back in time (the host clock was set mid-trial?)", f"line {k + 2}")
    return numbers, stamps


def fit_envelope(arduino_ms: np.ndarray, arrival_ns: np.ndarray) -> ArrivalFit:
    """The Arduino clock on the host clock: a line through the least-delayed line of each stretch
    of the log (ENVELOPE_BINS stretches of at least SAMPLES_PER_BIN lines), fitted by least
    squares. A late line, however late, is never the least delayed of its stretch."""
    x = np.asarray(arduino_ms, np.float64)
    y = (np.asarray(arrival_ns, np.int64) - int(arrival_ns[0])).astype(np.float64)   # ns, small numbers
    nominal = y - 1e6 * x
    bins = np.array_split(np.arange(len(x)), int(np.clip(len(x) // SAMPLES_PER_BIN, 1, ENVELOPE_BINS)))
    low = np.array([b[np.argmin(nominal[b])] for b in bins if len(b)])
    if len(low) >= 2 and x[low[-1]] > x[low[0]]:
        slope, intercept = np.polyfit(x[low], y[low], 1)
    else:                                  # one stretch: the nominal rate through its least-delayed line
        slope, intercept = 1e6, float(nominal[low[0]])
    above = y - (intercept + slope * x)
    return ArrivalFit(offset_ns=float(int(arrival_ns[0])) + intercept, ns_per_ms=float(slope),
                      median_delay_ms=float(np.median(above)) / 1e6,
                      p95_delay_ms=float(np.percentile(above, 95)) / 1e6)


def arduino_clock(path: Path, sample_lines: np.ndarray, arduino_ms: np.ndarray) -> ArrivalFit:
    """The Arduino clock on the host clock, from the arrival of the lines the samples came on;
    InputError naming force_arrival.csv when its stamps cannot be those lines'."""
    numbers, stamps = read_arrivals(path)
    at = np.searchsorted(numbers, sample_lines)
    found = (at < len(numbers)) & (numbers[np.minimum(at, len(numbers) - 1)] == sample_lines)
    if not found.all():
        missing = np.asarray(sample_lines)[~found]
        raise InputError(path, f"{len(missing)} sample lines of force.log have no arrival stamp (first: line "
                               f"{missing[0]}): the two files are not of one recording")
    if len(sample_lines) < 2:
        raise InputError(path, "fewer than 2 samples to fit the Arduino clock on")
    fit = fit_envelope(arduino_ms, stamps[at])
    if abs(fit.rate_ppm) > MAX_RATE_PPM:
        raise InputError(path, f"the Arduino clock would run {fit.rate_ppm:+.0f} ppm off the host's (at most "
                               f"±{MAX_RATE_PPM:g}): the arrival stamps are not of these lines")
    if fit.median_delay_ms > MAX_TYPICAL_DELAY_MS:
        raise InputError(path, f"lines reach the host a median {fit.median_delay_ms:.1f} ms after the Arduino's "
                               f"clock says (at most {MAX_TYPICAL_DELAY_MS:g}): the arrival stamps are not of these lines")
    return fit
