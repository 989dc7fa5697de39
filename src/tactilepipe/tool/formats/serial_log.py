"""The Arduino's serial log of the Nano17 (format in tool/formats/native_layout.py), parsed with counted drops.

Serial links garble lines: a partial first line when the port opens, a truncated last line when
logging stops, the odd corrupted byte. Such lines are dropped and counted (reported in the QC
report); a log where more than ``max_drop_fraction`` of the lines are bad, or whose Arduino clock
jumps backwards (a reset mid-trial, after which no single offset aligns the clocks), is an error.

A jump back that is a counter wrapping around is not a reset: ``millis()`` wraps at 2**32 ms, a
clock printed as ``micros() / 1000`` at 2**32 µs (4294967.296 ms, every 71.6 min of a board the
port's open does not reset). When the sample before sits just below the wrap and the one after
just above 0, one ordinary sample step apart, the times after it are unwrapped (the wrap is
listed in ``SerialLog.wraps``); a jump from near the wrap point with a gap after it is named as a
wrap that cannot be unwrapped, anything else as a reset.

A sample with any gauge channel at the 10-bit ADC rails (count 0 or ADC_COUNTS) is saturated: the
force was beyond the Nano17's range and calibrates to a clipped, too small value. Such samples are
dropped with the reason "ADC saturated" and counted (``SerialLog.saturated``), never passed on as a
force; they are well-formed lines, so they do not count towards ``max_drop_fraction``. A log whose
every sample is saturated (a gauge stuck at a rail: overload or a broken wire) is an error.
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tactilepipe.core.errors import InputError
from tactilepipe.core.rawfile import FORCE_LOG_MAX, read_raw_bytes
from tactilepipe.tool.formats.native_layout import ADC_COUNTS, SERIAL_HEADER

N_CHANNELS = 6
MAX_ARDUINO_MS = 2**32 - 1           # millis() is an unsigned 32-bit counter
MAX_HOST_NS = 2**62                  # host clock in ns since 1970: far beyond any real date
WRAPS = {"millis()": 2**32, "micros()/1000": 2**32 / 1000}    # where an Arduino clock in ms wraps to 0
WRAP_NEAR_MS = 10_000                # a jump back from this close below a wrap point is taken for one
_INT = re.compile(r"^-?[0-9]+$")     # plain decimal integers only (int() would take "1_0", "+1", " 1")
_GARBAGE = re.compile(r"[^\x20-\x7e\t\r]")   # non-ASCII (decoded as U+FFFD) and control bytes
SATURATED = "ADC saturated"          # drop reason of a sample with a gauge channel at the ADC rails


@dataclass
class SerialLog:
    start_host_ns: int
    arduino_ms: np.ndarray          # (n,) int64
    counts: np.ndarray              # (n, 6) ADC counts
    line_numbers: np.ndarray        # (n,) 1-based line of each kept sample, for error messages
    drops: Counter = field(default_factory=Counter)
    wraps: list[str] = field(default_factory=list)     # clock wraps unwrapped: "millis() at line N"

    @property
    def saturated(self) -> int:
        """Samples dropped because a gauge channel sat at the ADC rails (0 or ADC_COUNTS)."""
        return self.drops[SATURATED]


def at_adc_rails(counts: np.ndarray) -> np.ndarray:
    """(n,) True where any gauge channel of a sample reads 0 or ADC_COUNTS (saturated)."""
    counts = np.asarray(counts)
    return ((counts <= 0) | (counts >= ADC_COUNTS)).any(axis=1)


GARBAGE = "garbage bytes"


def parse_line(text: str) -> tuple[int, list[int]] | str:
    """(arduino_ms, counts) of one sample line (its line end removed), or the reason it is dropped."""
    if _GARBAGE.search(text):
        return GARBAGE
    if not text.strip():
        return "empty line"
    parts = [p.strip() for p in text.strip().split(",")]
    if len(parts) != 1 + N_CHANNELS:
        return "wrong column count"
    if not all(_INT.match(p) for p in parts):
        return "non-numeric field"
    values = [int(p) for p in parts]
    if values[0] < 0:
        return "negative time"
    if values[0] > MAX_ARDUINO_MS:
        return "time out of range"
    if any(not 0 <= v <= ADC_COUNTS for v in values[1:]):
        return "ADC count out of range"
    return values[0], values[1:]


def read_serial_log(path: str | Path, max_drop_fraction: float = 0.2) -> SerialLog:
    path = Path(path)
    try:
        data = read_raw_bytes(path, FORCE_LOG_MAX, "force.log")
    except FileNotFoundError:
        raise InputError(path, "missing: every trial needs the Arduino's force.log") from None
    # lines end at b"\n" only (str.splitlines would also split at stray \x0b, \x1c... bytes,
    # and the line numbers in messages would no longer be an editor's)
    lines = [ln.decode("ascii", errors="replace").removesuffix("\r") for ln in data.split(b"\n")]
    if lines and lines[-1] == "":
        lines.pop()
    if not lines:
        raise InputError(path, "serial log is empty")
    header = SERIAL_HEADER.match(lines[0])
    if not header:
        raise InputError(path, "first line must be '# start_host_ns=<int>'", "line 1")
    if int(header.group(1)) > MAX_HOST_NS:
        raise InputError(path, f"start_host_ns={header.group(1)} is out of range (ns since 1970)", "line 1")
    times, counts, numbers, drops = [], [], [], Counter()
    ends_clean = data.endswith(b"\n")
    for number, text in enumerate(lines[1:], start=2):
        parsed = parse_line(text)
        if isinstance(parsed, str):
            cut = number == len(lines) and not ends_clean and parsed != GARBAGE
            drops["truncated last line" if cut else parsed] += 1
            continue
        times.append(parsed[0])
        counts.append(parsed[1])
        numbers.append(number)
    total = len(lines) - 1
    if not times:
        raise InputError(path, f"no valid samples in {total} lines ({dict(drops)})")
    if sum(drops.values()) > max_drop_fraction * total:
        raise InputError(path, f"{sum(drops.values())} of {total} lines are unreadable ({dict(drops)}); "
                               f"more than {max_drop_fraction:.0%} means the link or the format is wrong")
    t = np.asarray(times, np.int64)
    c = np.asarray(counts, np.int64).reshape(-1, N_CHANNELS)
    numbers = np.asarray(numbers)
    t, wraps = _unwrap(path, t, numbers)
    steps = np.diff(t)
    if (steps == 0).any():
        k = int(np.argmax(steps == 0)) + 1
        raise InputError(path, f"duplicated Arduino timestamp {t[k]} ms", f"line {numbers[k]}")
    # the clock checks above include saturated samples (their times are valid); their forces are not
    saturated = at_adc_rails(c)
    if saturated.all():
        stuck = [ch for ch in range(N_CHANNELS) if at_adc_rails(c[:, [ch]]).all()]
        raise InputError(path, f"all {len(t)} samples have a gauge channel at the ADC rails (count 0 or "
                               f"{ADC_COUNTS}{f'; channel(s) {stuck} in every one' if stuck else ''}): "
                               f"the Nano17 is overloaded or a gauge is disconnected")
    if saturated.any():
        drops[SATURATED] += int(saturated.sum())
        keep = ~saturated
        t, c, numbers = t[keep], c[keep], numbers[keep]
    return SerialLog(int(header.group(1)), t, c, numbers, drops, wraps)


def _unwrap(path: Path, t: np.ndarray, numbers: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """``t`` with each counter wrap undone (see the module's docstring), and the wraps; a jump
    back that is no wrap is an error naming it as a reset, or as a wrap with a gap after it."""
    steps = np.diff(t)
    back = np.flatnonzero(steps < 0) + 1
    if not len(back):
        return t, []
    forward = steps[steps > 0]
    step = float(np.median(forward)) if len(forward) else 0.0
    out, wraps, added = t.astype(np.float64), [], 0.0
    for k in back:
        before, after = int(t[k - 1]), int(t[k])
        near = [(name, m) for name, m in WRAPS.items() if m - WRAP_NEAR_MS <= before < m]
        if not near:
            raise InputError(path, f"Arduino clock jumps back from {before} to {after} ms (a reset mid-trial?)",
                             f"line {numbers[k]}")
        name, modulus = near[0]
        gap = after + modulus - before
        if not 0 < gap <= max(4 * step, 1.0):
            raise InputError(path, f"Arduino clock wraps from {before} to {after} ms (its {name} counter passing "
                                   f"{modulus:.10g} ms) with {gap:.0f} ms between the samples, {gap / step if step else 0:.0f} "
                                   f"times the {step:.0f}-ms step: samples are missing there, not unwrapped",
                             f"line {numbers[k]}")
        added += modulus
        out[k:] = t[k:] + added
        wraps.append(f"{name} at line {numbers[k]}")
    return np.round(out).astype(np.int64), wraps
