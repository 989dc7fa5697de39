"""Witnesses of a native trial's force labels: evidence in the same recording that does not come
through the force chain (gauges -> ADC -> calibration -> zero -> Arduino clock), each able to say
when the labels are wrong (docs/robustness.md, "Every label has a witness").

Per trial, at ingest (``chain_witness`` before the clock is refined, ``label_witness`` after;
tolerances in tool_ingest.witness):

- unloaded ADC counts: the gauges' zero-force counts sit near the 10-bit ADC's mid level (the
  DAQ adaptor shifts 0 V to 2.5 V). An ADC reference of 3.3 V instead of 5 V puts them at ~775
  and scales every label by 1.52; a wrong level shift moves them too.
- declared rates: the frame rate meta.json declares against the frame stamps, and its serial rate
  against the Arduino's own clock (frames.csv stamped at 60 fps over frames taken at 30 pairs
  rest frames with loaded forces).
- rest at both ends: the force at the first and at the last frames of the trial, where the
  protocol rests, is zero within a tolerance at one end at least, whichever way it is off (a zero
  taken under a pull lifts every label; one taken under load lowers them; a recording that stops
  mid-press reads a load at its end only).
- zero drift: the start rests and the end reads a load that the images do not show (a finger
  back within a quarter of its change over the trial): the zero crept within the trial. A
  recording that stops mid-press shows its load in both fingers' images, and is kept.
- direction: while loaded, Fz carries most of |F| in both kinds of trial (a press, or a slide
  under a normal load with friction below 1): Fx/Fz swapped in nano17.cal leave Fz near 0.
- gauge wire: when the direction is wrong and the gauge a press moves most (from the
  calibration) stays within a few counts, its wire is open: named as such.
- exposure: a frame's mean brightness does not jump between frames (contact shades the gel
  locally; an exposure or LED step moves the whole frame).
- images: the tactile change from the reference frame follows |F| at the labels' clock
  (correlation; judged where the images change ``min_image_snr`` times their noise: a light press
  or a stiff gel barely moves them), with a gain (force per unit change) and an offset (force at zero change)
  that the session comparison (``session_outliers``, at the dataset stage) holds against the
  other trials of the session. A declared rate is compared with the trial's own stamps, and
  across the session as the ratio of the two, so a session may mix camera rates.

A failure is a short sentence with the numbers; the dataset leaves the trial out with it (qc.json
``dropped_trials``), never silently.
"""

from __future__ import annotations

import numpy as np

from tactilepipe.tool.data.clock_sync import REFERENCE_FRAMES, change_signal

ADC_MID = 511.5                      # counts at 2.5 V on a 10-bit, 5-V ADC (0..1023)


def _fps(host_ns: np.ndarray) -> float | None:
    return float(1e9 / np.median(np.diff(host_ns))) if len(host_ns) > 2 else None


def _period_ns(frames: dict) -> float:
    return float(np.median([np.median(np.diff(f.host_ns)) if len(f) > 1 else 1e9 / 30 for f in frames.values()]))


def _ratio_off(measured: float | None, declared: float | None, tolerance: float) -> bool:
    return bool(measured and declared and abs(np.log(measured / declared)) > np.log1p(tolerance))


def _image_fit(change: np.ndarray, mag: np.ndarray) -> tuple[float, float]:
    """(correlation, gain) of |F| against the tactile change; the gain is the 5-95 % range of |F|
    over that of the change, N per unit change. (Regressions either way, and the ratio at the
    loaded frames, spread as much or more within a pose of the simulated sessions: ~0.2 in log.)"""
    if len(change) < 3 or change.std() == 0 or mag.std() == 0:
        return float("nan"), float("nan")
    r = float(np.corrcoef(change, mag)[0, 1])
    lo, hi = np.percentile(change, [5, 95])
    gain = float(np.subtract(*np.percentile(mag, [95, 5])) / (hi - lo)) if hi > lo else float("nan")
    return r, gain


def image_snr(grays: np.ndarray) -> float:
    """How clearly a finger's images change over the trial: the 5-95 % range of its change from the
    reference over the frame-to-frame noise of that change (1.4826 MAD of the differences / sqrt 2)."""
    g = np.asarray(grays, np.float32)
    if len(g) < 5:
        return 0.0
    change = np.abs(g - np.median(g[:REFERENCE_FRAMES], axis=0)).mean(axis=(1, 2))
    d = np.diff(change)
    noise = 1.4826 * float(np.median(np.abs(d - np.median(d)))) / np.sqrt(2)
    return float(np.subtract(*np.percentile(change, [95, 5]))) / max(noise, 1e-6)


FLAT_GAUGE_COUNTS = 4.0                # 1st-99th percentile range of a channel that only sees ADC noise (0.6 counts)


def _flat_press_gauge(evidence: dict) -> tuple[int, float] | None:
    """(channel, range in counts) of the gauge a press moves most when it stays flat, else None."""
    ranges, channel = evidence.get("gauge_range_counts"), evidence.get("press_gauge")
    if ranges is None or channel is None or ranges[channel] > FLAT_GAUGE_COUNTS:
        return None
    return int(channel), float(ranges[channel])


def brightness_steps(grays: dict) -> dict[str, tuple[int, float]]:
    """Per finger, the largest change of a frame's mean brightness from one frame to the next (the
    frame before it, and the signed change in gray levels). Contact shades the gel locally, some
    parts brighter, some darker: the mean moves by a level or two; an exposure or LED step moves
    the whole frame."""
    out = {}
    for name, g in grays.items():
        if len(g) < 2:
            continue
        mean = np.asarray(g, np.float64).mean(axis=(1, 2))
        d = np.diff(mean)
        i = int(np.argmax(np.abs(d)))
        out[name] = (i, float(d[i]))
    return out


def chain_witness(evidence: dict, frames: dict, tol: dict) -> dict:
    """The witnesses that need no label: unloaded ADC counts and declared rates. Judged before the
    clock is refined, which a wrong rate would send astray (its error would name the clock).

    ``evidence``: RawTrial.evidence (native importer); ``frames``: sensor -> SensorFrames; ``tol``:
    params.yaml's tool_ingest.witness. Returns {"metrics": {...}, "failed": {name: why}}.
    """
    metrics, failed = {}, {}
    counts = evidence.get("unloaded_counts")
    if counts:
        worst = float(np.max(np.abs(np.asarray(counts) - ADC_MID)))
        metrics["unloaded_counts"] = counts
        metrics["adc_mid_gain"] = round(float(np.median(counts)) / ADC_MID, 4)
        if worst > tol["adc_mid_counts"]:
            failed["unloaded ADC counts"] = (
                f"the unloaded gauge counts are {', '.join(f'{c:.0f}' for c in counts)}, up to {worst:.0f} from the "
                f"ADC's mid level {ADC_MID:g} (tool_ingest.witness.adc_mid_counts {tol['adc_mid_counts']:g}): an ADC "
                f"reference other than 5 V (3.3 V reads ~775 and scales every label by 1.52) or a wrong level shift")
    fps = {name: _fps(f.host_ns) for name, f in frames.items()}
    metrics["fps"] = {k: round(v, 3) for k, v in fps.items() if v}
    declared = evidence.get("declared_fps")
    metrics["declared_fps"] = declared
    off = {k: v for k, v in fps.items() if _ratio_off(v, declared, tol["rate_rel"])}
    if off:
        failed["declared frame rate"] = (
            f"meta.json declares {declared:g} fps, frames.csv is stamped at "
            f"{', '.join(f'{k} {v:.1f} fps' for k, v in off.items())} (more than "
            f"{tol['rate_rel']:.0%} apart: tool_ingest.witness.rate_rel): stamps not of these frames")
    serial, declared_hz = evidence.get("serial_hz"), evidence.get("declared_serial_hz")
    metrics["serial_hz"] = round(serial, 3) if serial else None
    if _ratio_off(serial, declared_hz, tol["rate_rel"]):
        failed["declared serial rate"] = (
            f"meta.json declares {declared_hz:g} Hz, the Arduino's clock stamps force.log at {serial:.1f} Hz (more "
            f"than {tol['rate_rel']:.0%} apart): the Arduino's millis() does not run at 1 kHz, or another log")
    return {"metrics": metrics, "failed": failed}


def label_witness(witness: dict, evidence: dict, frames: dict, grays: dict, force_ns: np.ndarray,
                  force: np.ndarray, clock_trusted: bool, tol: dict) -> dict:
    """Adds the witnesses of the labels to ``witness`` (chain_witness's result): rest at both ends,
    force direction, and the images. Force on the clock the labels will use; ``clock_trusted``:
    that clock was refined or is a recorder's port-open clock (a host clock kept by on_low_score:
    host_clock is not, and the image correlation is then not judged)."""
    metrics, failed = witness["metrics"], witness["failed"]
    # labels at every frame of each finger, from the force on the labels' clock
    at = {name: np.stack([np.interp(f.host_ns, force_ns, force[:, a]) for a in range(3)], axis=1)
          for name, f in frames.items()}
    k = int(tol["rest_frames"])
    rest_fz = []
    first = min(int(f.host_ns[0]) for f in frames.values())
    bias_end = force_ns[0] + evidence.get("bias_window_s", 0.0) * 1e9
    log_ends = {"start": (force_ns > bias_end) & (force_ns < first),      # after the zero's window, before frame 0
                "end": force_ns >= force_ns[-1] - k * _period_ns(frames)}       # the log's last k frame periods
    for end, pick in (("start", slice(None, k)), ("end", slice(-k, None))):
        # at the trial's first (last) frames and on the log beyond them: the lower of the two, so that
        # a label clock a few frames off at a press's end is not read as an offset (the images judge it)
        levels = [(float(np.median([np.linalg.norm(np.median(v[pick], axis=0)) for v in at.values()])),
                   float(np.median([np.median(v[pick, 2]) for v in at.values()])))]
        if log_ends[end].sum() >= 2:
            tail = np.median(force[log_ends[end]], axis=0)
            levels.append((float(np.linalg.norm(tail)), float(tail[2])))
        level, fz = min(levels)
        rest_fz.append(fz)
        metrics[f"rest_{end}_n"] = round(level, 4)
    # a zero taken off true zero shifts both ends alike; one end alone is no offset (a recording
    # may stop mid-press, or start with the tool already touching)
    if min(metrics["rest_start_n"], metrics["rest_end_n"]) > tol["rest_n"]:
        failed["rest at both ends"] = (
            f"|F| reads {metrics['rest_start_n']:.2f} N over the {k} first frames and {metrics['rest_end_n']:.2f} N "
            f"over the {k} last (and on the force log beyond them), where the trial rests "
            f"(tool_ingest.witness.rest_n {tol['rest_n']:g} N): the zero-force offset is off by about that "
            f"(taken under load or under a pull)")
    metrics["rest_fz_n"] = round(float(np.mean(rest_fz)), 4)     # signed: the session compares it
    vec = np.concatenate(list(at.values()))
    mag = np.linalg.norm(vec, axis=1)
    loaded = mag >= max(tol["loaded_n"], 0.3 * float(mag.max(initial=0.0)))
    if loaded.sum() >= 3:
        share = float(np.median(np.abs(vec[loaded, 2]) / mag[loaded]))
        metrics["normal_share"] = round(share, 4)
        flat = _flat_press_gauge(evidence)
        if share < tol["min_normal_share"] and flat:
            failed["gauge wire"] = (
                f"while loaded (|F| up to {mag.max():.1f} N) Fz carries a median {share:.0%} of |F|, and gauge channel "
                f"{flat[0]}, the one a press moves most (nano17.cal), stays within {flat[1]:.0f} counts over the trial: "
                f"its wire is open or its amplifier dead")
        elif share < tol["min_normal_share"]:
            failed["force direction"] = (
                f"while loaded (|F| up to {mag.max():.1f} N) Fz carries a median {share:.0%} of |F| (at least "
                f"{tol['min_normal_share']:.0%}: tool_ingest.witness.min_normal_share): a press and a slide load the "
                f"tip along the Nano17's z axis; the axes of nano17.cal are swapped or the sensor is mounted sideways")
    steps = brightness_steps(grays)
    metrics["brightness_step_dn"] = {k: round(v[1], 2) for k, v in steps.items()}
    jumped = {k: v for k, v in steps.items() if v[1] > tol["max_brightness_step_dn"]}
    if jumped:
        failed["exposure"] = "; ".join(
            f"{k}'s mean brightness jumps by {v:+.1f} gray levels from frame {i} to {i + 1}" for k, (i, v) in
            jumped.items()) + (f" (at most tool_ingest.witness.max_brightness_step_dn {tol['max_brightness_step_dn']:g}; "
                               f"contact moves it under 3): an exposure or LED change, which the images would "
                               f"show the model as a change of force")
    changes = {name: change_signal(grays[name]) for name in frames}
    fits = {name: _image_fit(changes[name], np.linalg.norm(at[name], axis=1)) for name in frames}
    r, gain = (float(np.nanmean([f[i] for f in fits.values()])) if any(np.isfinite(f[i]) for f in fits.values())
               else float("nan") for i in range(2))
    metrics.update({"image_score": round(r, 4), "image_gain": round(gain, 4), "clock_trusted": clock_trusted})
    # a light press, or a stiff gel, barely moves the images (not above their noise at a small stored
    # size): they cannot judge its labels, which then rest on the clock alone
    snr = max(image_snr(grays[name]) for name in frames)
    metrics["image_snr"] = round(snr, 2)
    metrics["images_judge"] = judge = bool(snr >= tol["min_image_snr"])    # their gain and lag are compared only then
    if clock_trusted and judge:
        _zero_drift(metrics, failed, changes, k, tol)
        if np.isfinite(r) and r < tol["min_image_score"]:
            failed["images"] = (
                f"the tactile change follows |F| with correlation {r:.2f} at the labels' clock (at least "
                f"{tol['min_image_score']:g}: tool_ingest.witness.min_image_score): the labels are not of these "
                f"frames (a clock or frame-rate error pairs rest frames with loaded forces)")
    return {"metrics": metrics, "failed": failed}


def _zero_drift(metrics: dict, failed: dict, changes: dict, k: int, tol: dict) -> None:
    """The zero crept within the trial: it rests at its start (where the zero was taken) and reads a
    load at its end that the images do not show. A finger's images are back at rest when their
    change at the last frames is within ``rest_change_frac`` of its 5-95 % range from the first;
    one finger back at rest is enough (the simulated grasp can leave the other finger's gel
    shifted, up to 0.6 of its range in clean trials, and a press that stops loaded loads both)."""
    def from_start(change: np.ndarray) -> float:
        lo, hi = np.percentile(change, [5, 95])
        return float((np.median(change[-k:]) - np.median(change[:k])) / (hi - lo)) if hi > lo else float("nan")
    frac = min(from_start(c) for c in changes.values())
    metrics["end_change_frac"] = round(frac, 4)
    start, end = metrics["rest_start_n"], metrics["rest_end_n"]
    if start <= tol["rest_n"] < end and frac <= tol["rest_change_frac"]:
        failed["zero drift"] = (
            f"|F| reads {end:.2f} N over the {k} last frames (and on the force log beyond them) and "
            f"{start:.2f} N over the {k} first, while the images are back at rest there (a finger's change "
            f"{frac:+.0%} of its range from the start; tool_ingest.witness.rest_change_frac "
            f"{tol['rest_change_frac']:g}): the Nano17's zero drifted by about {end:.2f} N within the trial "
            f"(temperature, a cable moving)")


# --- the session comparison (dataset stage) -----------------------------------------------------

def _values(info: dict) -> dict:
    """The compared quantities of one trial (None where not measured)."""
    m = info.get("witness", {}).get("metrics", {})
    gain = m.get("image_gain")
    fingers = info.get("clock", {}).get("finger_shift_s") or {}
    lag = None
    if len(fingers) == 2 and m.get("clock_trusted"):
        a, b = fingers.values()
        lag = float(a) - float(b)
    fps = list((m.get("fps") or {}).values())
    # a session may mix camera rates, each declared in its meta.json: the rate compared is the stamps'
    # against the trial's own declaration (a camera whose clock runs off stands out among them)
    declared = m.get("declared_fps") or 1.0
    trusted = m.get("clock_trusted") and m.get("images_judge", True)
    return {"gain": float(np.log(gain)) if trusted and gain and gain > 0 else None,
            "offset": m.get("rest_fz_n"),
            "lag": lag, "rate": float(np.log(np.mean(fps) / declared)) if fps else None}


def session_outliers(infos: list[dict], cmp: dict) -> dict[int, str]:
    """Index -> why, for each trial whose gain, offset, finger lag or frame rate stands out from the
    other trials of its session (for the gain: of its tool and pose), when there are at least
    ``min_trials`` others: robust z = (x - median) / max(1.4826 MAD, floor) of the others, beyond
    ``max_z``.
    ``cmp``: params.yaml's tool_sync.witness."""
    values = [_values(i) for i in infos]
    session = [i["trial"].split("/")[0] for i in infos]
    pose = [f"{i['tool']}@{float(i['orientation_deg']):.1f}/{float(i['insertion_mm']):.1f}" for i in infos]
    out: dict[int, list[str]] = {}
    floors = {"gain": cmp["gain_floor"], "offset": cmp["offset_floor_n"], "lag": cmp["lag_floor_s"],
              "rate": cmp["rate_floor"]}
    for what, floor in floors.items():
        for i, v in enumerate(values):
            x = v[what]
            if x is None or not np.isfinite(x):
                continue
            # the gain depends on the tool and the grasp: compared within the pose when it has enough trials
            same = [j for j in range(len(infos)) if j != i and session[j] == session[i]
                    and (what != "gain" or pose[j] == pose[i]) and values[j][what] is not None
                    and np.isfinite(values[j][what])]
            if len(same) < cmp["min_trials"]:
                continue
            others = np.array([values[j][what] for j in same])
            med = float(np.median(others))
            spread = max(1.4826 * float(np.median(np.abs(others - med))), floor)
            z = (x - med) / spread
            if abs(z) > cmp["max_z"]:
                shown = {"gain": lambda y: f"{np.exp(y):.3g} N per unit change",
                         "offset": lambda y: f"Fz {y:+.2f} N at rest", "lag": lambda y: f"{y * 1000:+.0f} ms",
                         "rate": lambda y: f"stamps at {np.exp(y):.4f} x the declared rate"}[what]
                group = "pose" if what == "gain" else "session"
                out.setdefault(i, []).append(
                    f"{what} {shown(x)} against the {group}'s median {shown(med)} over its {len(same)} other trials "
                    f"(robust z {z:+.1f}, beyond tool_sync.witness.max_z {cmp['max_z']:g})")
    return {i: "stands out from its session: " + "; ".join(w) for i, w in out.items()}
