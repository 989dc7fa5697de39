"""PapillArray physics shared by the volume and drift simulators: how a pressed wall loads the nine
pillars, the pillar's measuring range, the minimum-jerk motion of a lift or a placed weight."""

from __future__ import annotations

import numpy as np

from tactilepipe.papillarray import messages as pa

G = 9.81
SESSION_EPOCH_S = 1_767_225_600  # 2026-01-01T00:00:00Z: simulated sessions start here


def minimum_jerk(t: np.ndarray, duration: float, height: float) -> tuple[np.ndarray, np.ndarray]:
    """Position and acceleration of a minimum-jerk move from 0 to ``height`` over ``duration``."""
    tau = np.clip(t / duration, 0.0, 1.0)
    z = height * (10 * tau**3 - 15 * tau**4 + 6 * tau**5)
    acc = height / duration**2 * (60 * tau - 180 * tau**2 + 120 * tau**3)
    acc = np.where((t >= 0) & (t <= duration), acc, 0.0)
    return z, acc


def pillar_offsets_mm(steps: list[float]) -> np.ndarray:
    """How far each pillar tip sits below the centre tip (centre, edge and corner heights)."""
    centre, edge, corner = steps
    return np.array([corner, edge, corner, edge, centre, edge, corner, edge, corner], float)


def normal_load_map(grip: np.ndarray, offsets: np.ndarray, tilt: np.ndarray, pitch: float,
                    k_n: float) -> np.ndarray:
    """Pillar normal forces (T, 9) for a flat wall pressed with total force ``grip`` (T,).

    The wall is a plane z = d + tilt·(x, y); pillar i is compressed by max(0, z - offset_i).
    d is found by bisection so the forces sum to the grip (the sum is monotonic in d).
    """
    x = (pa.PILLAR_ROWCOL[:, 1] - 1) * pitch
    y = (1 - pa.PILLAR_ROWCOL[:, 0]) * pitch
    gap = offsets - (tilt[0] * x + tilt[1] * y)          # depth at which pillar i starts touching
    lo = np.full_like(grip, gap.min())
    hi = lo + grip / k_n + (gap.max() - gap.min()) + 1e-9
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        total = k_n * np.clip(mid[:, None] - gap[None, :], 0.0, None).sum(axis=1)
        too_deep = total > grip
        hi = np.where(too_deep, mid, hi)
        lo = np.where(too_deep, lo, mid)
    d = 0.5 * (lo + hi)
    fz = k_n * np.clip(d[:, None] - gap[None, :], 0.0, None)
    return np.where(grip[:, None] > 0, fz, 0.0)


def saturate(measured: np.ndarray, sim: dict) -> tuple[np.ndarray, np.ndarray]:
    """Clip readings (..., 3) to the pillar's measuring range and flag what was clipped.

    The PapillArray measures each pillar tip's displacement and reports force through its
    stiffness; a tip beyond the tracked travel (``pillar_travel_mm``) reads as the travel's edge:
    +-k_t travel on fX, fY and +-k_n travel on fZ. Returns the clipped readings and a same-shape
    mask of the saturated values (a reading at the limit, never NaN)."""
    travel = sim["pillar_travel_mm"]
    limit = travel * np.array([sim["pillar_tangential_stiffness_n_per_mm"]] * 2
                              + [sim["pillar_normal_stiffness_n_per_mm"]], float)
    clipped = np.clip(measured, -limit, limit)
    return clipped, np.abs(measured) >= limit
