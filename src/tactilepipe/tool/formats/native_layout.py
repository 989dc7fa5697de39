"""The native raw layout of a tool-force recording, as the rig writes it (and the simulator too).

    raw/tool/<session>/
      nano17.cal                  ATI calibration (XML; UserAxis rows: N per V for the 6 gauges)
      <trial>/
        meta.json                 tool, grasp pose, trial kind (see TrialMeta)
        digit_left/frames.csv     frame,host_ns     (host clock, one row per frame; the numbers skip the
                                                    frames the camera dropped, which have no PNG)
        digit_left/frame_000000.png ...             BGR uint8, portrait 240 wide x 320 high (QVGA; VGA
                                                    and landscape frames are read too: DIGIT_SIZES)
        digit_right/...           same for the other finger
        force.log                 the Arduino's serial output, see below

force.log: line 1 is `# start_host_ns=<int>` written by the host logger when it opened the
port (only good to ~0.1 s: the offset is refined from the data); then one line per sample at
~15 Hz: `<arduino_ms>,<a0>,<a1>,<a2>,<a3>,<a4>,<a5>`, the Arduino's own millisecond clock and
the six Nano17 gauge channels as 10-bit ADC counts (0..1023 over 0..5 V, 512 at 2.5 V = 0 V
gauge output through the DAQ adaptor's level shift). Forces are F = C · (v − v_bias), v the
gauge voltage (counts · 5/1023 − 2.5), C the 6×6 matrix of nano17.cal, v_bias the mean of the
zero-force samples at the start of the trial.
"""

from __future__ import annotations

import json
import math
import re
import xml.etree.ElementTree as ET
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from tactilepipe.core.errors import InputError
from tactilepipe.core.rawfile import META_MAX, TABLE_MAX, read_raw_bytes, read_raw_text
from tactilepipe.tool.formats.calibration_structure import AXES, RATED_RANGE, check_structure

SENSORS = ("digit_left", "digit_right")
FRAME_W, FRAME_H = 240, 320          # portrait QVGA, as digit-interface returns it
# (height, width) of the DIGIT's stream modes, QVGA and VGA, either way up: the model sees every
# frame resized to a square, so a trial's size only has to be one the sensor streams (and one
# orientation per dataset: tool/data/dataset.py)
DIGIT_SIZES = ((320, 240), (240, 320), (640, 480), (480, 640))
ADC_COUNTS, ADC_VOLTS = 1023, 5.0
ADC_ZERO_V = 2.5
# ATI's unit names in a .cal file, as factors to N and N·mm (the units the pipeline works in)
FORCE_UNITS = {"N": 1.0, "kN": 1000.0, "lbf": 4.4482216152605, "klbf": 4448.2216152605, "Klbf": 4448.2216152605,
               "g": 0.00980665, "kg": 9.80665, "kgf": 9.80665}
TORQUE_UNITS = {"N-mm": 1.0, "N-m": 1000.0, "kN-m": 1e6, "lbf-in": 112.98482933, "lbf-ft": 1355.8179483,
                "klbf-in": 112984.82933, "Klbf-in": 112984.82933, "kgf-cm": 98.0665, "g-cm": 0.0980665}
# The Nano17 SI-25-0.25's rated ranges (ATI; RATED_RANGE): Fx, Fy ±25 N, Fz ±35 N, torques ±250 N·mm.
# A matrix must map the ADC's whole span (5 V) to forces between a quarter and a hundred times these:
# beyond, a cell is out by orders of magnitude (a typo, another unit, another sensor's file).
SPAN_FACTORS = (0.25, 100.0)
MAX_CONDITION = 1e4                  # the simulated sessions' matrices: ~11
FRAME_NAME = "frame_{:06d}.png"
SERIAL_HEADER = re.compile(r"^#\s*start_host_ns=([0-9]+)\s*$")
_UINT = re.compile(r"^[0-9]+$")
TOOL_NAME = re.compile(r"[a-z0-9_]+")
_INT = re.compile(r"^-?[0-9]+$")


# plausible values of a trial's metadata: beyond, a unit or a typo (a pose in radians or metres)
META_RANGES = {"orientation_deg": (-360.0, 360.0, "degrees of tilt of the tool axis in the pad plane"),
               "insertion_mm": (0.0, 200.0, "mm from the gel's fingertip edge to the butt end: within a tool's length"),
               "camera_fps": (1.0, 240.0, "a DIGIT streams at 15-60 fps"),
               "serial_hz": (1.0, 10000.0, "samples per second of the Arduino's log")}


@dataclass
class TrialMeta:
    trial: str
    tool: str
    kind: str                          # "normal" (pressing) or "shear" (sliding)
    orientation_deg: float             # tilt of the tool axis in the grasp
    insertion_mm: float                # how deep the handle sits between the fingers
    camera_fps: float = 30.0
    serial_hz: float = 15.0
    notes: dict = field(default_factory=dict)

    def write(self, trial_dir: str | Path) -> None:
        from tactilepipe.core.atomic import write_json
        write_json(Path(trial_dir) / "meta.json", asdict(self))

    @classmethod
    def read(cls, trial_dir: str | Path) -> "TrialMeta":
        path = Path(trial_dir) / "meta.json"
        try:
            raw = json.loads(read_raw_text(path, META_MAX, "trial's meta.json"))
        except FileNotFoundError:
            raise InputError(path, "missing: every trial needs meta.json") from None
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise InputError(path, f"not valid JSON: {exc}") from None
        return cls.from_dict(raw, path)

    @classmethod
    def from_dict(cls, raw, where: str | Path, default_trial: str | None = None) -> "TrialMeta":
        """Validated metadata from a mapping (meta.json, a bag's sidecar): every required key,
        no unknown key, kind normal/shear, non-empty names, finite numbers."""
        if isinstance(raw, cls):
            raw = asdict(raw)
        if not isinstance(raw, dict):
            raise InputError(where, f"trial metadata must be a JSON object, got {type(raw).__name__}")
        raw = dict(raw)
        if default_trial is not None:
            raw.setdefault("trial", default_trial)
        missing = {"trial", "tool", "kind", "orientation_deg", "insertion_mm"} - set(raw)
        if missing:
            raise InputError(where, f"trial metadata missing keys {sorted(missing)}")
        unknown = set(raw) - set(cls.__dataclass_fields__)
        if unknown:
            raise InputError(where, f"trial metadata has unknown keys {sorted(unknown)}")
        if raw["kind"] not in ("normal", "shear"):
            raise InputError(where, f"kind '{raw['kind']}' must be normal or shear")
        for key in ("trial", "tool"):
            if not isinstance(raw[key], str) or not raw[key]:
                raise InputError(where, f"{key} must be a non-empty string, got {raw[key]!r}")
        check_tool_name(raw["tool"], where)
        for key in ("orientation_deg", "insertion_mm", "camera_fps", "serial_hz"):
            value = raw.get(key, 0.0)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise InputError(where, f"{key} must be a finite number, got {value!r}")
            low, high, why = META_RANGES[key]
            if key in raw and not low <= value <= high:
                raise InputError(where, f"{key} {value!r} is outside {low:g} to {high:g} ({why})")
        return cls(**raw)


def frame_orientation(width: int, height: int) -> str:
    """portrait, landscape or square: after the square resize a model only suits frames standing
    the way its training frames stood."""
    return "portrait" if height > width else "landscape" if width > height else "square"


def check_tool_name(tool: str, where, record: str | None = None) -> None:
    """A tool's name becomes part of file and run names (results/<build>/<scene>/models/full_loto_<tool>):
    lowercase letters, digits and _ only, refused here rather than as a missing file later."""
    if not TOOL_NAME.fullmatch(tool):
        suggestion = re.sub(r"[^a-z0-9_]+", "_", tool.strip().lower()).strip("_") or "tool_1"
        raise InputError(where, f"tool name {tool!r} must be lowercase letters, digits and _ (it names the "
                                f"leave-one-tool-out runs and their files), e.g. {suggestion!r}", record)


def read_frame_index(sensor_dir: str | Path) -> np.ndarray:
    """host_ns of every frame frames.csv lists (see read_frame_table)."""
    return read_frame_table(sensor_dir)[1]


def read_frame_table(sensor_dir: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(frame numbers, host_ns) of every frame frames.csv lists. The numbers increase and may skip
    (the camera dropped those frames: no row, no PNG); a number listed twice or going back, or
    stamps that do not increase, are refused."""
    path = Path(sensor_dir) / "frames.csv"
    if not path.exists():
        raise InputError(path, "missing: every sensor folder needs frames.csv (frame,host_ns)")
    data = read_raw_bytes(path, TABLE_MAX, "frames.csv")
    try:
        lines = data.removeprefix(b"\xef\xbb\xbf").decode("ascii").split("\n")   # BOM: a spreadsheet
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise InputError(path, f"non-ASCII byte 0x{exc.object[exc.start]:02x}: not a frames.csv written by the rig",
                         f"line {line}") from None
    lines = [ln.removesuffix("\r") for ln in lines]
    if lines and lines[-1] == "":
        lines.pop()
    if not lines or lines[0].strip() != "frame,host_ns":
        raise InputError(path, "header must be 'frame,host_ns'", "line 1")
    numbers = np.empty(len(lines) - 1, np.int64)
    stamps = np.empty(len(lines) - 1, np.int64)
    for i, line in enumerate(lines[1:]):
        parts = [p.strip() for p in line.split(",")]
        if len(parts) != 2 or not _UINT.match(parts[0]) or not _INT.match(parts[1]):
            raise InputError(path, f"expected 'frame,host_ns' integers, got {line!r}", f"line {i + 2}")
        number = int(parts[0])
        if number >= 10 ** 6:                    # FRAME_NAME's six digits: 9 hours at 30 fps
            raise InputError(path, f"frame number {number} is beyond 999999 (frame_NNNNNN.png)", f"line {i + 2}")
        if i and number <= numbers[i - 1]:
            how = "listed twice" if number == numbers[i - 1] else f"out of order (after {numbers[i - 1]})"
            raise InputError(path, f"frame number {number} {how}: frame numbers must increase", f"line {i + 2}")
        if not -2**63 < int(parts[1]) < 2**63:
            raise InputError(path, f"host_ns {parts[1]} does not fit in 64 bits", f"line {i + 2}")
        numbers[i], stamps[i] = number, int(parts[1])
    if len(stamps) and (np.diff(stamps) <= 0).any():
        k = int(np.argmax(np.diff(stamps) <= 0)) + 1
        raise InputError(path, "frame timestamps do not increase (clock jump or duplicate)", f"line {k + 2}")
    return numbers, stamps


def write_calibration(path: str | Path, matrix: np.ndarray, serial: str = "FT-SIM-0001") -> None:
    """An ATI-style .cal XML with six UserAxis rows (N or N·mm per volt)."""
    from tactilepipe.core.atomic import write_text
    root = ET.Element("FTSensor", Serial=serial, BodyStyle="Nano17", Family="DAQ", NumGages="6")
    cal = ET.SubElement(root, "Calibration", PartNumber="SI-25-0.25", ForceUnits="N", TorqueUnits="N-mm")
    for name, row in zip(AXES, matrix):
        ET.SubElement(cal, "UserAxis", Name=name, values=" ".join(f"{v:.8g}" for v in row))
    write_text(path, ET.tostring(root, encoding="unicode") + "\n")


def read_calibration(path: str | Path) -> np.ndarray:
    path = Path(path)
    try:
        root = ET.fromstring(read_raw_bytes(path, META_MAX, "calibration file"))
    except FileNotFoundError:
        raise InputError(path, "missing: the session needs the Nano17 calibration file") from None
    except ET.ParseError as exc:
        raise InputError(path, f"not valid calibration XML: {exc}") from None
    spaces = sorted({el.tag[1:].split("}", 1)[0] for el in root.iter() if el.tag.startswith("{")})
    if spaces:                              # its UserAxis rows would read as missing
        raise InputError(path, f"the XML declares the namespace {spaces[0]!r} (xmlns): ATI's calibration files "
                               f"have none, so its elements are not <Calibration> and <UserAxis>; if this is the "
                               f"Nano17's ATI file, remove the xmlns declaration")
    rows = {ax.get("Name"): ax.get("values", "") for ax in root.iter("UserAxis")}
    if set(AXES) - set(rows):
        raise InputError(path, f"UserAxis rows missing: {sorted(set(AXES) - set(rows))}")
    names = [ax.get("Name") for ax in root.iter("UserAxis")]
    twice = sorted({n for n in names if names.count(n) > 1 and n in AXES})
    if twice:
        raise InputError(path, f"UserAxis rows given more than once: {twice}")
    values = {}
    for a in AXES:
        try:
            values[a] = [float(v) for v in rows[a].split()]
        except ValueError as exc:
            raise InputError(path, f"non-numeric calibration value: {exc}", f"UserAxis {a}") from None
        if len(values[a]) != 6:
            raise InputError(path, f"calibration rows need 6 values, got {len(values[a])}", f"UserAxis {a}")
    matrix = np.array([values[a] for a in AXES])
    if not np.isfinite(matrix).all():
        a = AXES[int(np.argmax(~np.isfinite(matrix).all(axis=1)))]
        raise InputError(path, "calibration values must be finite numbers", f"UserAxis {a}")
    factors = _unit_factors(path, root)
    _check_cells(path, matrix, factors)
    matrix = matrix * factors[:, None]
    _check_matrix(path, matrix)
    check_structure(path, matrix)           # a cell off by 10x against the other rows, a transposed matrix
    return matrix


def _check_cells(path: Path, matrix: np.ndarray, factors: np.ndarray) -> None:
    """Refuse a cell that alone maps the ADC's span beyond the sensor's plausible range: named by
    its row and column, before the whole matrix is judged (its condition number would only say
    "singular", or overflow)."""
    high = SPAN_FACTORS[1] * RATED_RANGE
    with np.errstate(over="ignore", invalid="ignore"):
        span = np.abs(matrix) * factors[:, None] * ADC_VOLTS
    for (i, j) in zip(*np.nonzero(~(span <= high[:, None]))):
        unit = "N" if AXES[i].startswith("F") else "N·mm"
        raise InputError(path, f"value {j + 1} of the row, {matrix[i, j]:.6g}, is out of range: alone it maps the "
                               f"ADC's {ADC_VOLTS:g} V to {span[i, j]:.3g} {unit}, beyond {high[i]:.3g} {unit} "
                               f"(the Nano17's rated ±{RATED_RANGE[i]:g} {unit} times {SPAN_FACTORS[1]:g})",
                         f"UserAxis {AXES[i]}")


def _unit_factors(path: Path, root) -> np.ndarray:
    """Per row, the factor from the file's units to N (forces) and N·mm (torques)."""
    cal = root if root.tag == "Calibration" else root.find(".//Calibration")
    units = {key: (cal.get(key) if cal is not None else None) for key in ("ForceUnits", "TorqueUnits")}
    for key, table in (("ForceUnits", FORCE_UNITS), ("TorqueUnits", TORQUE_UNITS)):
        if units[key] not in table:
            found = "no " + key if units[key] is None else f"{key}={units[key]!r}"
            raise InputError(path, f"{found} on <Calibration>: the unit must be one of {', '.join(table)}")
    return np.array([FORCE_UNITS[units["ForceUnits"]]] * 3 + [TORQUE_UNITS[units["TorqueUnits"]]] * 3)


def _check_matrix(path: Path, matrix: np.ndarray) -> None:
    """Refuse a matrix no Nano17 has: singular or nearly (a row copied into another), or one whose
    rows map the ADC's span to forces far outside the sensor's rated range."""
    singular = np.linalg.svd(matrix, compute_uv=False)
    condition = singular[0] / singular[-1] if singular[-1] > 0 else math.inf
    if not condition <= MAX_CONDITION:
        raise InputError(path, f"the 6x6 matrix is singular or nearly (condition number {condition:.3g}, at most "
                               f"{MAX_CONDITION:.0e}): the six gauges cannot be told apart")
    span = np.abs(matrix).sum(axis=1) * ADC_VOLTS
    low, high = SPAN_FACTORS[0] * RATED_RANGE, SPAN_FACTORS[1] * RATED_RANGE
    for axis, value, lo, hi in zip(AXES, span, low, high):
        if not lo <= value <= hi:
            unit = "N" if axis.startswith("F") else "N·mm"
            raise InputError(path, f"the row maps the ADC's {ADC_VOLTS:g} V to {value:.3g} {unit}, outside "
                                   f"{lo:.3g}-{hi:.3g} {unit} (the Nano17's rated ±{RATED_RANGE[AXES.index(axis)]:g} "
                                   f"{unit} times {SPAN_FACTORS[0]:g}-{SPAN_FACTORS[1]:g})", f"UserAxis {axis}")


def calibrate(counts: np.ndarray, matrix: np.ndarray, bias_counts: np.ndarray) -> np.ndarray:
    """Forces/torques (n, 6) from gauge counts: F = C (v - v_bias)."""
    volts = counts_to_volts(counts) - counts_to_volts(bias_counts)
    return volts @ matrix.T


def counts_to_volts(counts: np.ndarray) -> np.ndarray:
    return np.asarray(counts, np.float64) * (ADC_VOLTS / ADC_COUNTS) - ADC_ZERO_V
