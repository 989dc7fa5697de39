"""Each lift against the other lifts of its session: its sensors, then its volume label.

Two kinds of evidence, neither of which comes from the label:

- **The sensors against the session** (``standing_out``). Every lift of a session is read by the
  same two pads, biased the same way, so what the physics keeps fixed from lift to lift must agree:
  each sensor's rest level (Fy, Fz before the grasp), each pad's share of the carried load (the
  pads' tangential stiffness ratio) and each pad's share of the grip (the container's horizontal
  equilibrium: both pads squeeze with the same normal force). A lift whose value lies further
  from the session's median than ``outlier_k`` robust standard deviations (1.4826 x MAD), and more
  than the measure's floor, stands out: a sensor offset, a gain on one sensor, a loose cable. It
  is left out of the data set with the evidence in ``qc.csv`` and ``scores.json``. The grip
  level itself is not compared: under a position or re-tightening grip it follows the load.
- **The label against the weight** (``check_labels``). Off the table the pads carry the container
  and its water, (m_container + rho V) g. Over the session's kept lifts, a robust line
  (Theil-Sen) of the carried load against the labelled volume has the container's weight as
  its intercept, unknown to the analysis, and rho g as its slope. A slope off 9.81 mN per ml
  (``label_slope_rel_tol``), or a lift off the line by more than ``outlier_k`` robust standard
  deviations of the session's residuals and ``label_floor_n``, is refused with its numbers.

Where no slope can be fitted (fewer than ``min_session_lifts`` kept lifts, or one volume), the
lifts are held to a lower bound instead: the pads carry at least the labelled water's weight (80 %,
less 0.5 N), whatever the container weighs. A session under ``min_session_lifts`` is not compared
or fitted at all, and ``qc.csv`` says so.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tactilepipe.core.errors import InputError

WATER_N_PER_ML = 9.81e-3      # 1 g of water per ml, in N
ROBUST_SD = 1.4826            # MAD -> standard deviation of a normal sample
LOWER_BOUND_SHARE = 0.8       # a small session: the pads carry at least this share of the labelled water's
LOWER_BOUND_SLACK_N = 0.5     # weight, less this much (bias and drift of the two sensors)


def lift_evidence(rec: dict, start: int, stop: int, rest: int) -> dict:
    """What one lift's forces say, label aside: each sensor's rest level (median of the first
    ``rest`` samples, before the grasp), the vertical load each pad carries off the table above
    its rest level (median over [start, stop)), their sum, and sensor 1's share of the grip."""
    out = {}
    grip = []
    for s in (0, 1):
        fy, fz = rec[f"fy{s}"], rec[f"fz{s}"]
        out[f"rest_fy{s}"] = float(np.median(fy[:rest]))
        out[f"rest_fz{s}"] = float(np.median(fz[:rest]))
        out[f"load{s}_n"] = float(np.median(fy[start:stop])) - out[f"rest_fy{s}"]
        grip.append(float(np.median(fz[start:stop])))
    out["carried_n"] = out["load0_n"] + out["load1_n"]
    out["grip_share1"] = grip[1] / (grip[0] + grip[1]) if grip[0] + grip[1] > 0 else float("nan")
    return out


def _robust(x: np.ndarray) -> tuple[float, float]:
    """Median and robust standard deviation (1.4826 x MAD) of the finite values of ``x``."""
    x = x[np.isfinite(x)]
    med = float(np.median(x))
    return med, ROBUST_SD * float(np.median(np.abs(x - med)))


def standing_out(ev: pd.DataFrame, checks: dict) -> dict[str, str]:
    """{lift: evidence} for each lift of ``ev`` (one session's lifts that did not slip; columns
    lift and those of ``lift_evidence``) whose sensors stand out from the session's."""
    k = checks["outlier_k"]
    found: dict[str, list[str]] = {}

    def compare(values: np.ndarray, floor: float, say) -> None:
        med, sd = _robust(values)
        tol = max(k * sd, floor)
        for lift, v in zip(ev["lift"], values):
            if not abs(v - med) <= tol:            # NaN stands out too
                found.setdefault(lift, []).append(say(v, med, tol))

    for s in (0, 1):
        for axis in ("y", "z"):
            compare(ev[f"rest_f{axis}{s}"].to_numpy(), checks["rest_floor_n"],
                    lambda v, m, t, s=s, a=axis: f"sensor {s} rests at F{a} {v:+.3f} N, the session's lifts at "
                                                 f"{m:+.3f} N (tolerance {t:.3f} N): an offset")
    carried = ev["carried_n"].to_numpy()
    share, _ = _robust(ev["load1_n"].to_numpy() / carried)
    compare(ev["load1_n"].to_numpy() - share * carried, checks["load_share_floor_n"],
            lambda v, m, t: f"sensor 1 carries {v - m:+.3f} N more than the session's share {share:.3f} of the "
                            f"load (tolerance {t:.3f} N): a gain on one sensor's Fy")
    compare(ev["grip_share1"].to_numpy(), checks["grip_share_floor"],
            lambda v, m, t: f"sensor 1 takes {v:.3f} of the two pads' grip, the session's lifts {m:.3f} "
                            f"(tolerance {t:.3f}; both pads squeeze alike): a gain on one sensor's Fz")
    return {lift: "; ".join(says) for lift, says in found.items()}


def _theil_sen(volume: np.ndarray, load: np.ndarray) -> float:
    """Median of the slopes between every two lifts of different volumes."""
    i, j = np.triu_indices(len(volume), 1)
    ok = volume[i] != volume[j]
    return float(np.median((load[j] - load[i])[ok] / (volume[j] - volume[i])[ok]))


def check_labels(ev: pd.DataFrame, checks: dict, source) -> list[str]:
    """Refuse the labels of one session's kept lifts that their carried load contradicts; return
    each lift's label check for qc.csv. ``ev``: columns lift, volume_ml and carried_n; ``source``
    names the error (the session's lifts.csv)."""
    volume, load = ev["volume_ml"].to_numpy(np.float64), ev["carried_n"].to_numpy(np.float64)
    if not np.isfinite(load).all():        # a fit through NaN would be NaN, and every comparison with it false
        raise InputError(source, "; ".join(f"lift {lift}: the pads' carried load is {c}" for lift, c
                                           in zip(ev["lift"], load) if not np.isfinite(c)) + ": no weight to check")
    n_volumes = len(np.unique(volume))
    if len(ev) < checks["min_session_lifts"] or n_volumes == 1:     # no slope to fit: the lower bound's unit check
        low = LOWER_BOUND_SHARE * volume * WATER_N_PER_ML - LOWER_BOUND_SLACK_N
        bad = [f"lift {lift}: lifts.csv gives {v:g} ml ({v * WATER_N_PER_ML:.2f} N of water) but the pads carry "
               f"{c:.2f} N off the table" for lift, v, c, lo in zip(ev["lift"], volume, load, low) if not c >= lo]
        if bad:
            raise InputError(source, "; ".join(bad) + ": a wrong row or unit in lifts.csv (volume_ml is in "
                                                      "millilitres)?")
    if len(ev) < checks["min_session_lifts"]:
        return [f"lower bound only: {len(ev)} lifts in the session, under volume_checks.min_session_lifts "
                f"{checks['min_session_lifts']}"] * len(ev)
    slope = _theil_sen(volume, load) if n_volumes > 1 else WATER_N_PER_ML
    ratio = slope / WATER_N_PER_ML
    if not abs(ratio - 1) <= checks["label_slope_rel_tol"]:
        raise InputError(source, f"the lifts' carried load grows by {slope * 1000:.4g} mN per unit of volume_ml "
                                 f"(robust fit over {len(ev)} lifts, {n_volumes} volumes), water weighs "
                                 f"{WATER_N_PER_ML * 1000:.2f} mN per ml: {ratio:.4g} x, beyond "
                                 f"volume_checks.label_slope_rel_tol {checks['label_slope_rel_tol']:g}. "
                                 f"volume_ml must be in millilitres (litres read 1000 x), or both sensors' gain "
                                 f"is off")
    intercept = float(np.median(load - slope * volume))
    expected = intercept + slope * volume
    resid = load - expected
    _, sd = _robust(resid)
    tol = max(checks["outlier_k"] * sd, checks["label_floor_n"])
    off = np.flatnonzero(~(np.abs(resid) <= tol))
    if len(off):
        raise InputError(source, "; ".join(
            f"lift {ev['lift'].iloc[i]}: lifts.csv gives {volume[i]:g} ml, the pads carry {load[i]:.3f} N off the "
            f"table, the session's fit expects {expected[i]:.3f} ± {tol:.3f} N: its load is that of "
            f"{(load[i] - intercept) / slope:.0f} ml" for i in off)
            + f" (fit over {len(ev)} lifts: container {intercept:.3f} N + {slope * 1000:.3f} mN per ml). A wrong "
              f"label in lifts.csv, or a gain on both sensors of that lift")
    note = "" if n_volumes > 1 else " (one volume: water's slope assumed, not fitted)"
    return [f"on the session's fit: {r:+.3f} N of ± {tol:.3f} N (about {tol / slope:.0f} ml){note}" for r in resid]
