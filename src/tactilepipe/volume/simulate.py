"""Simulated lifts of a water-filled container held by two PapillArray sensors (study 001).

Physics, per 500 Hz sample:
- Robotiq grip (``grip_regime``, see ``grasp.py``): in the default ``force`` regime the normal
  force per pad ramps to the force setting (with lift-to-lift repeatability) and does not depend
  on the load; ``position`` closes to a width (pads and container wall in series, stiffer with
  less headspace air), ``retighten`` raises the grip while loaded pillars slip.
- Normal load map: a rigid wall pressed into 9 linear-spring pillars of different heights
  (centre tallest), slightly tilted; the indentation is solved so the pillar forces sum to the grip.
- Lift: minimum-jerk 10 cm lift, hold, place. The pads carry min(K·z, m(g + a)): the container
  stays on the table until the pad springs carry its weight. The two pads share the load in
  proportion to their tangential stiffness; a small grasp tilt puts part of it on x.
- Friction: each pillar sticks while |f_t| <= mu_s f_z and slides at mu_k f_z otherwise (an exact
  active-set solve per sample), so lightly loaded outer pillars slip first.
- Measurement: viscoelastic creep of the silicone pillars (`viscoelastic.py`: the reading lags
  load changes and creeps to them; a stiff ODE, integrated exactly between samples by default),
  pillar noise, residual bias after the driver's bias request, thermal drift
  dF(t) = dF_inf (1 - exp(-t / tau)) since the last bias (growing with the carried load), and the
  pillar's measuring range (readings beyond it are clipped to it and counted, never NaN).
Nothing here writes the volume or the off-table interval into the bag; labels go to lifts.csv.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tactilepipe.papillarray import messages as pa
from tactilepipe.core.atomic import write_text
from tactilepipe.papillarray.bagio import write_bag
from tactilepipe.volume import grasp
from tactilepipe.papillarray import viscoelastic
from tactilepipe.papillarray.physics import (G, SESSION_EPOCH_S, minimum_jerk, normal_load_map,
                                            pillar_offsets_mm, saturate)

POSE_TOPIC = "/tool_pose"
POSE_BASE_Z_M = 0.12  # tool height when the container stands on the table
CONTACT_N = 0.05      # a pillar pressing harder than this is "in contact" (the driver's flag)


@dataclass(frozen=True)
class Lift:
    """One recorded lift: its bag name, label and position in the recording session."""
    name: str
    volume_ml: float
    kind: str          # "main" (the 7 trained volumes) or "unseen"
    block: int         # volume block: the sensors are biased when a block starts
    index: int         # lift index within the block


def session_plan(sim: dict) -> list[Lift]:
    """All lifts of a simulated session, in recording order (one block per volume)."""
    lifts = []
    blocks = [(v, "main", sim["lifts_per_volume"]) for v in sim["volumes_ml"]]
    blocks += [(v, "unseen", sim["unseen_lifts_per_volume"]) for v in sim["unseen_volumes_ml"]]
    for b, (volume, kind, count) in enumerate(blocks):
        for i in range(count):
            lifts.append(Lift(f"v{int(round(volume)):03d}_{kind}_l{i:02d}", float(volume), kind, b, i))
    return lifts


def _smooth_step(t: np.ndarray, start: float, duration: float) -> np.ndarray:
    return minimum_jerk(t - start, duration, 1.0)[0]


@dataclass
class Timeline:
    t: np.ndarray          # s since the recording started
    grip: np.ndarray       # normal force per pad, N
    envelope: np.ndarray   # gripper closure: 0 open, 1 closed (the grip's ramps)
    z: np.ndarray          # tool lift above the table position, m
    acc: np.ndarray        # tool vertical acceleration, m/s^2
    phases: dict           # phase name -> (start, end) s


def lift_timeline(sim: dict, rate_hz: float, grip_force: float, lift_s: float) -> Timeline:
    pre, close, settle, hold, opening, post = 0.3, 0.6, 0.3, sim["hold_duration_s"], 0.4, 0.3
    t_lift = pre + close + settle
    t_hold = t_lift + lift_s
    t_place = t_hold + hold
    t_open = t_place + lift_s + settle
    total = t_open + opening + post
    t = np.arange(int(round(total * rate_hz))) / rate_hz
    envelope = _smooth_step(t, pre, close) - _smooth_step(t, t_open, opening)
    grip = grip_force * envelope
    z_up, a_up = minimum_jerk(t - t_lift, lift_s, sim["lift_height_m"])
    z_dn, a_dn = minimum_jerk(t - t_place, lift_s, sim["lift_height_m"])
    phases = {"close": (pre, pre + close), "lift": (t_lift, t_hold), "hold": (t_hold, t_place),
              "place": (t_place, t_place + lift_s), "open": (t_open, t_open + opening)}
    return Timeline(t, grip, envelope, z_up - z_dn, a_up - a_dn, phases)


class PadFriction:
    """Stick/slip state of one pad's 9 pillars, advanced one sample at a time.

    Each step solves exactly which pillars stick: the sticking ones share one pad displacement u,
    sliding ones pull with mu_k f_z along their stretch. A regime whose grip reacts to slip
    (``retighten``) needs the slip of sample k before it sets the grip of sample k + 1, so the
    solve is a step, not a whole-lift function.
    """

    def __init__(self, k_t: float, mu_s: float, mu_k: float):
        self.k_t, self.mu_s, self.mu_k = k_t, mu_s, mu_k
        self.anchor = np.zeros((9, 2))   # where each pillar's spring is unstretched (moves when it slides)
        self.u = np.zeros(2)

    def step(self, demand: np.ndarray, fz: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
        """Pillar shear (9, 2), slipping flags (9,) and gross slip for shear ``demand`` (2,) and
        pillar normal forces ``fz`` (9,)."""
        k_t, mu_s, mu_k, anchor = self.k_t, self.mu_s, self.mu_k, self.anchor
        u = self.u
        contact = fz > 0
        anchor[~contact] = u      # a pillar off the wall relaxes and re-sticks where it lands
        stick = contact.copy()
        slide_force = np.zeros((9, 2))
        for _ in range(10):
            n_stick = stick.sum()
            pull = slide_force[contact & ~stick].sum(axis=0)
            if n_stick == 0:
                break
            u = (demand - pull + k_t * anchor[stick].sum(axis=0)) / (k_t * n_stick)
            f = k_t * (u - anchor)
            mag = np.linalg.norm(f, axis=1)
            over = stick & (mag > mu_s * fz)
            if not over.any():
                break
            # the most overloaded pillars start sliding at the kinetic limit along their stretch
            slide_force[over] = (mu_k * fz[over] / mag[over])[:, None] * f[over]
            stick &= ~over
        f = np.where(stick[:, None], k_t * (u - anchor), slide_force)
        f[~contact] = 0.0
        sliding = contact & ~stick
        gross = False
        if stick.sum() == 0 and contact.any():
            cap = mu_k * fz[contact].sum()
            want = np.linalg.norm(demand)
            gross = bool(want > cap)
            direction = demand / want if want > 0 else np.zeros(2)
            f[contact] = (mu_k * fz[contact])[:, None] * direction
        # a sliding pillar's anchor follows so that its spring holds exactly the kinetic force
        anchor[sliding] = u - f[sliding] / k_t
        self.u = u
        return f, sliding, gross


def tangential_forces(demand: np.ndarray, fz: np.ndarray, k_t: float, mu_s: float, mu_k: float
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stick/slip pillar shear for one pad over time.

    demand: (T, 2) shear (x, y) the pad must carry; fz: (T, 9) pillar normal forces.
    Returns pillar shear (T, 9, 2), slipping flags (T, 9) and gross-slip flags (T,) (the whole pad
    slides: it carries only the kinetic limit).
    """
    n = len(demand)
    pad = PadFriction(k_t, mu_s, mu_k)
    forces = np.zeros((n, 9, 2))
    slipping = np.zeros((n, 9), bool)
    gross = np.zeros(n, bool)
    for k in range(n):
        forces[k], slipping[k], gross[k] = pad.step(demand[k], fz[k])
    return forces, slipping, gross


def sensor_properties(seed: int, sim: dict) -> dict:
    """Per-sensor constants of this rig (fixed for a session): stiffness factors."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 1001]))
    mismatch = sim["sensor_stiffness_mismatch"] * rng.uniform(0.5, 1.0) * rng.choice([-1, 1])
    return {"k_factor": np.array([1 + mismatch / 2, 1 - mismatch / 2])}


def simulate_lift(lift: Lift, sim: dict, seed: int) -> dict:
    """Simulate one lift; returns per-sample pillar forces of both sensors and the tool pose."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, int(round(lift.volume_ml * 10)),
                                                        lift.index, 0 if lift.kind == "main" else 1]))
    props = sensor_properties(seed, sim)
    rate = sim["rate_hz"]
    mass = (sim["container_mass_g"] + lift.volume_ml) / 1000.0      # water: 1 g per ml
    k_n, k_t = sim["pillar_normal_stiffness_n_per_mm"], sim["pillar_tangential_stiffness_n_per_mm"]
    offsets = pillar_offsets_mm(sim["pillar_height_steps_mm"])
    repeat = rng.standard_normal()      # lift-to-lift repeatability of the grasp (force or width)
    if sim["grip_regime"] == "position":
        pos = sim["position"]
        grip_force = grasp.position_grip_n(pos, lift.volume_ml, pos["squeeze_mm"] + pos["squeeze_std_mm"] * repeat,
                                           offsets, k_n)
    else:
        grip_force = sim["grip_force_n"] * (1 + sim["grip_force_rel_std"] * repeat)
    lift_s = sim["lift_duration_s"] * (1 + 0.03 * rng.standard_normal())
    tl = lift_timeline(sim, rate, grip_force, lift_s)
    n = len(tl.t)

    grasp_tilt = np.deg2rad(sim["grasp_tilt_std_deg"]) * rng.standard_normal()

    # Load carried by the pads: the container leaves the table once the pad springs hold m(g + a).
    k_pads = 2 * 9 * k_t * 1000.0                              # N/m, all pillars sticking
    carried = np.minimum(k_pads * np.clip(tl.z, 0, None), mass * (G + tl.acc))
    carried = np.where(tl.grip > 0, carried, 0.0)
    share = props["k_factor"] / props["k_factor"].sum()

    tilts = [np.tan(np.deg2rad(sim["contact_tilt_std_deg"]) * rng.standard_normal(2)) for _ in range(2)]
    # y points down the pad (positive when the container pulls down); sensor 1 faces sensor 0,
    # so its x axis is mirrored
    demands = [(share[s] * carried)[:, None] * np.array([np.sin(grasp_tilt) * (1 if s == 0 else -1),
                                                         np.cos(grasp_tilt)])[None, :] for s in range(2)]
    k_ts = [k_t * props["k_factor"][s] for s in range(2)]
    if sim["grip_regime"] == "retighten":
        force, slip, gross, grip = retightened_pads(tl, grip_force, tilts, demands, k_ts, offsets, sim)
    else:
        force = np.zeros((n, 2, 9, 3))
        slip = np.zeros((n, 2, 9), bool)
        gross = np.zeros(n, bool)
        grip = tl.grip
        for s in range(2):
            fz = normal_load_map(tl.grip, offsets, tilts[s], sim["pillar_pitch_mm"], k_n)
            ft, slip[:, s], g = tangential_forces(demands[s], fz, k_ts[s],
                                                  sim["friction_static"], sim["friction_kinetic"])
            gross |= g
            force[:, s, :, :2], force[:, s, :, 2] = ft, fz

    # Measurement: viscoelastic creep of the pillars (the reading lags the load), bias residual,
    # thermal drift since the block's bias request, white noise, and the sensor's range.
    t_since_bias = lift.index * sim["lift_cycle_s"] + tl.t
    drift_inf = sim["drift_inf_n"] + sim["drift_per_kg_n"] * carried / G
    drift = drift_inf * (1 - np.exp(-t_since_bias / sim["drift_tau_s"]))
    measured = viscoelastic.integrate_params(force, 1.0 / rate, sim)
    if sim["crosstalk_t_to_n"]:
        measured = grasp.add_crosstalk(measured, sim["crosstalk_t_to_n"])
    measured += sim["bias_residual_std_n"] * rng.standard_normal((1, 2, 9, 3))
    measured[..., 2] += (drift / 9.0)[:, None, None]
    measured += sim["noise_std_n"] * rng.standard_normal(measured.shape)
    measured, saturated = saturate(measured, sim)

    stiffness = np.array([k_t, k_t, k_n])
    in_contact = force[..., 2] > CONTACT_N
    pose_t = np.arange(0, tl.t[-1], 1.0 / sim["pose_rate_hz"])
    pose_z = POSE_BASE_Z_M + np.interp(pose_t, tl.t, tl.z) + 2e-5 * rng.standard_normal(len(pose_t))
    return {"t": tl.t, "force": measured.astype(np.float32), "disp": (measured / stiffness).astype(np.float32),
            "in_contact": in_contact, "slip": slip, "pose_t": pose_t, "pose_z": pose_z,
            "off_table": (carried >= mass * (G + tl.acc) - 1e-12) & (tl.z > 0), "gross_slip": gross,
            "phases": tl.phases, "true_force": force, "grip": grip, "saturated": saturated,
            "saturated_samples": int(saturated.any(axis=(1, 2, 3)).sum())}


def retightened_pads(tl: Timeline, grip_force: float, tilts: list, demands: list, k_ts: list,
                     offsets: np.ndarray, sim: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Both pads, sample by sample, under a grip raised while loaded pillars slip.

    While the gripper is closed, a slip of any pillar in contact (either pad) seen ``latency_s``
    earlier raises the grip by ``rate_n_per_s`` per second, up to ``max_grip_n``; the raise is kept
    for the rest of the hold and opens with the gripper. Returns true forces (T, 2, 9, 3), slip
    flags (T, 2, 9), gross slip (T,) and the grip per pad (T,)."""
    rt, rate = sim["retighten"], sim["rate_hz"]
    n = len(tl.t)
    lag = int(round(rt["latency_s"] * rate))
    pads = [PadFriction(k, sim["friction_static"], sim["friction_kinetic"]) for k in k_ts]
    force = np.zeros((n, 2, 9, 3))
    slip = np.zeros((n, 2, 9), bool)
    gross = np.zeros(n, bool)
    grip = np.zeros(n)
    seen = np.zeros(n, bool)          # a loaded pillar slipped at this sample
    extra, fz = 0.0, None
    for k in range(n):
        if tl.envelope[k] >= 1.0 and k >= lag and seen[k - lag]:
            extra = min(extra + rt["rate_n_per_s"] / rate, max(0.0, rt["max_grip_n"] - grip_force))
        grip[k] = tl.envelope[k] * (grip_force + extra)
        if fz is None or grip[k] != grip[k - 1]:      # the load map only changes with the grip
            fz = [normal_load_map(grip[k:k + 1], offsets, tilts[s], sim["pillar_pitch_mm"],
                                  sim["pillar_normal_stiffness_n_per_mm"])[0] for s in range(2)]
        for s in range(2):
            ft, slip[k, s], g = pads[s].step(demands[s][k], fz[s])
            gross[k] |= g
            force[k, s, :, :2], force[k, s, :, 2] = ft, fz[s]
        seen[k] = bool((slip[k] & (force[k, :, :, 2] > CONTACT_N)).any())
    return force, slip, gross, grip


def lift_start_ns(lift: Lift, sim: dict) -> int:
    block_s = 600.0 * lift.block      # each volume block starts 10 min after the previous one
    return int(round((SESSION_EPOCH_S + block_s + lift.index * sim["lift_cycle_s"]) * 1e9))


def write_lift_bag(path: str | Path, lift: Lift, sim: dict, seed: int) -> dict:
    """Simulate ``lift`` and write it as a ROS1 bag the way papillarray_ros_v2 publishes it."""
    rec = simulate_lift(lift, sim, seed)
    start = lift_start_ns(lift, sim)
    stamps = start + np.round(rec["t"] * 1e9).astype(np.int64)
    tus = np.round((stamps - SESSION_EPOCH_S * 1_000_000_000) / 1000).astype(np.int64)
    topics = {}
    for s in range(2):
        # slip_state: 1 while the pillar slides over the wall (stick/slip solve), else 0
        raws = pa.encode_sensor_states(stamps, tus, rec["disp"][:, s], rec["force"][:, s],
                                       rec["in_contact"][:, s], rec["slip"][:, s].astype(np.int32),
                                       frame_id=f"hub_0/sensor_{s}")
        topics[pa.sensor_topic(0, s)] = (pa.SENSOR_STATE, stamps.tolist(), raws)
    pose_stamps = start + np.round(rec["pose_t"] * 1e9).astype(np.int64)
    pos = np.zeros((len(pose_stamps), 3))
    pos[:, 0], pos[:, 2] = 0.45, rec["pose_z"]
    topics[POSE_TOPIC] = (pa.POSE_STAMPED, pose_stamps.tolist(), pa.encode_pose_stamped(pose_stamps, pos))
    write_bag(path, topics)
    return rec


def write_session_labels(session_dir: str | Path, lifts: list[Lift]) -> None:
    """lifts.csv: what the lab notes down for every bag (its file, the filled volume, its set)."""
    rows = ["bag,volume_ml,set"] + [f"{l.name}.bag,{l.volume_ml:g},{l.kind}" for l in lifts]
    write_text(Path(session_dir) / "lifts.csv", "\n".join(rows) + "\n")


# lifts.csv is read by volume/labels.py; the name stays importable from here
