"""The camera's latency, from every arrival-stamped trial of a session, and each trial held to it.

A trial whose serial lines were stamped on arrival has its force on the host clock
(tool/formats/arrival_log.py). A camera frame is stamped on the host too, but some tens of ms
after its exposure (USB transfer, the driver's queue), and the envelope of the serial arrivals
carries a small constant delay of its own. Both are fixed for a rig: one number per session,
the lag at which |F| best explains the tactile images. One trial's image fit scatters by tens of
ms (a slow press, a slide whose images follow the shear more than |F|); the median over the
session's trials does not. So:

- the session's latency is the median of the usable per-trial lags of its pressing trials whose
  images change enough to judge (ingest's ``clock.images``, the witness's ``images_judge``), and
  every label of the session is taken that much before its frame pair's stamp;
- a pressing trial whose own usable lag lies more than ``max_lag_error_s`` from the session's is left out,
  named: its force log or its frames are not of one moment (stamps shifted, another trial's
  samples, frames repeated or skipped);
- a session with no usable lag (light presses only) keeps latency 0 and says so in qc.json.
"""

from __future__ import annotations

import numpy as np

ARRIVAL = "serial_arrival"
# Only pressing trials tell the latency: a slide's images follow the shear strokes more than |F|,
# whose normal load barely moves, and their best lags scatter by +-0.2 s (the default session)
PRESSING = "normal"


def _usable(info: dict) -> bool:
    """The trial's image lag counts: the fit was trusted, and its images change enough to judge."""
    judge = info.get("witness", {}).get("metrics", {}).get("images_judge", True)
    return bool(info.get("clock", {}).get("images", {}).get("usable")) and judge and info["kind"] == PRESSING



def session_of(info: dict) -> str:
    return info["trial"].split("/")[0]


def camera_latency(infos: list[dict]) -> dict[str, dict]:
    """Per session with arrival-stamped trials: the latency (s, None without evidence), how many
    trials gave it, and the spread (interquartile range) of their lags."""
    lags: dict[str, list[float]] = {}
    for info in infos:
        clock = info.get("clock", {})
        if clock.get("method") != ARRIVAL:
            continue
        images = clock.get("images", {})
        lags.setdefault(session_of(info), [])
        if _usable(info):
            lags[session_of(info)].append(float(images["refined_shift_s"]))
    out = {}
    for session, values in lags.items():
        if values:
            q1, q2, q3 = np.percentile(values, [25, 50, 75])
            out[session] = {"latency_s": round(float(q2), 4), "trials": len(values), "iqr_s": round(float(q3 - q1), 4)}
        else:
            out[session] = {"latency_s": None, "trials": 0,
                            "note": "no trial's images gave a lag (light presses only?): labels at the frames' stamps"}
    return out


def shift_ns(info: dict, latencies: dict[str, dict]) -> int:
    """What to add to a trial's force times so that a frame pair's stamp reads the force at its exposure."""
    if info.get("clock", {}).get("method") != ARRIVAL:
        return 0
    latency = latencies.get(session_of(info), {}).get("latency_s")
    return int(round(latency * 1e9)) if latency is not None else 0


def lag_outlier(info: dict, latencies: dict[str, dict], max_error_s: float) -> str | None:
    """Why a trial's images contradict its session's clock, or None."""
    clock = info.get("clock", {})
    images = clock.get("images", {})
    session = latencies.get(session_of(info), {})
    if clock.get("method") != ARRIVAL or not _usable(info) or session.get("latency_s") is None:
        return None
    error = float(images["refined_shift_s"]) - session["latency_s"]
    if abs(error) <= max_error_s:
        return None
    return (f"witness 'clock': the images follow |F| at {images['refined_shift_s'] * 1000:+.0f} ms, the session's "
            f"camera latency is {session['latency_s'] * 1000:+.0f} ms over {session['trials']} trials: "
            f"{error * 1000:+.0f} ms apart (at most tool_sync.witness.max_lag_error_s {max_error_s * 1000:.0f} ms): "
            f"the force log's stamps or the frames are not of this moment")
