"""How the gripper sets the normal force on the pads: the grasp regimes of the volume simulator.

``simulate_volume.grip_regime`` chooses one (the physics and the magnitudes are argued in
docs/volume.md):

- ``force``: the Robotiq's force setting is the normal force per pad, whatever the container
  holds (the gripper stops closing once its motor current reaches the setting).
- ``position``: the gripper closes to a width, ``squeeze_mm`` past first contact. The normal force
  is what that squeeze produces in the two pads and the container wall, springs in series. The
  wall is a thin PET ring (Roark's ring under two opposite loads) in parallel with, when the
  container is capped, the headspace air that a dimple in the wall compresses: the less air above
  the water, the stiffer the wall. This is the only way the fill level reaches the grip force in
  a slow squeeze: water is incompressible but transmits, not adds, stiffness; the pressure it
  transmits is the headspace gas's (capped) or hydrostatic (open, negligible).
- ``retighten``: the grip starts at the force setting and is raised at a bounded rate while any
  loaded pillar slips (incipient slip, as the PapillArray's per-pillar slip flags report it),
  after a detection latency; it is never lowered while the container is held. The loop itself is
  in ``simulate.retightened_pads`` (it needs the stick/slip state of every sample).

``crosstalk_t_to_n`` (any regime) is a sensor property, applied in the simulator's measurement
step: each pillar reports this fraction of its shear magnitude as extra normal force.
"""

from __future__ import annotations

import numpy as np

# Change of a thin ring's diameter along two opposite point loads W: 0.1488 W R^3 / (E I)
# (Roark's Formulas for Stress and Strain, thin circular rings).
RING_DIAMETRAL_COEFF = 0.1488


def pad_indentation_mm(force_n: float | np.ndarray, offsets: np.ndarray, k_n: float) -> np.ndarray:
    """How far the centre pillar of an untilted pad is pressed in to carry ``force_n`` in total.

    Pillar i carries k_n max(0, d - offset_i), so the total is piecewise linear in d; it is
    inverted at its breakpoints (the tilt of the contact shifts this by far less than the wall's
    compliance, so the position regime ignores it here; the load map still uses it)."""
    breaks = np.unique(np.concatenate([[0.0], offsets]))
    breaks = np.append(breaks, breaks[-1] + 1.0)          # beyond the last step: every pillar touches
    total = k_n * np.clip(breaks[:, None] - offsets[None, :], 0.0, None).sum(axis=1)
    force = np.asarray(force_n, float)
    last_slope = k_n * len(offsets)
    return np.where(force <= total[-1], np.interp(force, total, breaks),
                    breaks[-1] + (force - total[-1]) / last_slope)


def wall_stiffness_n_per_mm(pos: dict, volume_ml: float) -> float:
    """Stiffness of the container's diameter against the two pads, N/mm (``pos``: the
    ``simulate_volume.position`` group)."""
    inertia = pos["wall_contact_length_mm"] * pos["wall_thickness_mm"] ** 3 / 12.0      # mm^4
    ring = pos["wall_modulus_mpa"] * inertia / (RING_DIAMETRAL_COEFF * pos["container_radius_mm"] ** 3)
    if not pos["container_capped"]:
        return float(ring)
    # isothermal headspace: a squeeze of the diameter by x dimples both walls over the dimple area,
    # taking A x of the air's volume V; the pressure rise p0 A x / V acts back on each pad over A
    air_mm3 = (pos["container_capacity_ml"] - volume_ml) * 1000.0
    p0 = pos["atmospheric_kpa"] * 1e-3                                                  # N/mm^2
    return float(ring + p0 * pos["dimple_area_mm2"] ** 2 / air_mm3)


def position_grip_n(pos: dict, volume_ml: float, squeeze_mm: float, offsets: np.ndarray, k_n: float) -> float:
    """Normal force per pad when the fingers close ``squeeze_mm`` past first contact.

    The squeeze is shared by the two pads and the wall: squeeze = 2 d_pad(F) + F / k_wall, solved
    for F by bisection (the right-hand side grows with F)."""
    if squeeze_mm <= 0:
        return 0.0
    k_wall = wall_stiffness_n_per_mm(pos, volume_ml)
    lo, hi = 0.0, squeeze_mm * k_wall          # the wall alone would take the whole squeeze
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if 2 * pad_indentation_mm(mid, offsets, k_n) + mid / k_wall > squeeze_mm:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def add_crosstalk(measured: np.ndarray, fraction: float) -> np.ndarray:
    """Readings (..., 3) with ``fraction`` of each pillar's shear magnitude added to its normal
    force (the sensor's tangential-to-normal cross-talk)."""
    out = measured.copy()
    out[..., 2] += fraction * np.linalg.norm(measured[..., :2], axis=-1)
    return out
