"""Simulated tool-force recordings of study 000: two DIGITs grasp a tool pressed on a Nano17.

Writes what the real rig writes (tactilepipe.tool.formats.native_layout): per trial the PNG frames of both
DIGITs with host timestamps, the Arduino's serial log of the six Nano17 gauges and meta.json;
per session nano17.cal. The true tip force goes only into force.log (through the calibration,
as quantised ADC counts with noise, on the Arduino's own clock) - never into frames or meta.

Frames (gripper frame: n = finger normal, left pad -> right pad; u across the pads; z up, the
fingers point down, the tool tip below them):
- Grasp: the handle lies between the two gel pads, its axis in the pad plane tilted by the
  pose's orientation, its butt end ``insertion_mm`` from the fingertip edge of the gel (a deeper
  insertion means a longer contact line and a shorter lever arm to the tip). The gripper holds
  its position; the grip preload presses the handle into both gels (depth 2q/(pi E*) per unit
  line load q, the Hertz line-contact law; width b = sqrt(2 R depth) = sqrt(4 q R/(pi E*))). The
  tool's weight hangs on the pads too: both are in the zero-force reference frame.
- Tip force: the Nano17 pushes on the tip with R = (R_n, R_u, F_N). The tool is a rigid body on
  two elastic line foundations (springs along each contact line, normal stiffness pi E*/2 and
  tangential stiffness per mm of line); its small 6-DOF displacement solves K q = W with the
  wrench W of the tip reaction and the weight about the grasp centre. The moment
  r_tip x R (lever arm from the insertion depth and the tilt) is resisted by torsion of both
  gels, by differential shear (rotation about u moves the two pads' surfaces in opposite z
  directions, the handle's half-thickness being the lever) and by a centre-of-pressure shift
  (one end of each line presses deeper, opposite ends on the two fingers). So the two fingers
  see different imprints that depend on the pose: on the tilt, on the insertion, and on the
  hand-set grasp's unrecorded lean out of the pad plane (and a cranked tool's tip offset).
  During pressing the tip sticks on the sensor cap: friction takes ``tip_pin_fraction`` of the
  tip's tendency to slide sideways (REFERENCE: M = L (F_N sin(theta) - R_x cos(theta))),
  bounded by the tip friction. The pads stick (no slip; |T| <= mu N is checked per pad).
- Normal trials: pressing cycles (minimum-jerk rise, hold, fall) with rests at 0 N between
  them; peaks from a Beta distribution skewed to light presses, plus a small force ripple.
- Shear trials: the tip is loaded to a few newtons and slid back and forth in strokes along an
  axis (slide.stroke_axis_deg, with a spread); the tip friction mu F_N opposes the sliding
  velocity (regularised Coulomb law); standing still between strokes and while loading, the tip
  is pinned by static friction as in a press.
- Images: see digit_render.py (height field, Taxim softening, saturation at h_max, shear remap,
  three-LED shading, noise, LED flicker, background drift). Each sensor has its own look, gel
  stiffness, frame-rate error and exposure-to-stamp latency (fixed for the session).
- Nano17 + Arduino: the force on the sensor is -R in the sensor frame (x = n, y = u, z up), so a
  press reads Fz < 0 as on a real ATI sensor mounted tool side up (``nano17.mount: upright``;
  ``inverted`` turns it over: a press reads Fz > 0); torques from the contact point on the cap. Gauge
  voltages v = C^-1 F + v_bias (C from the session's nano17.cal, v_bias per gauge), 10-bit ADC
  counts with noise. The Arduino resets when the host opens the port (``start_host_ns``) and
  starts its millis() clock 0.05-0.5 s later (unknown per trial); its crystal runs off by tens
  of ppm; each line is stamped with millis() and the gauges are read a few ms later (jitter).

Determinism: every random draw comes from np.random.SeedSequence([seed, stream, ...]); a trial's
draws depend only on the seed, the tool name, the pose, the kind and the trial number, so the
same seed gives byte-identical files whatever else is in the plan.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from tactilepipe.core.atomic import atomic_path, write_text
from tactilepipe.core.errors import ConfigError
from tactilepipe.tool.sim import render as dr
from tactilepipe.tool.formats import native_layout as layout

G = 9.81
SESSION_EPOCH_S = 1_767_225_600     # 2026-01-01T00:00:00Z: simulated sessions start here
KINDS = ("normal", "shear")
STREAM_CAL, STREAM_RIG, STREAM_LOOK, STREAM_TRIAL = 4001, 4002, 4003, 4004
TRUTH_RATE_HZ = 1000.0              # rate of the returned ground-truth series (tests only)


# --- plan -------------------------------------------------------------------------------------

@dataclass(frozen=True)
class TrialSpec:
    """One recorded trial: what the lab notes down (tool, nominal grasp pose, kind)."""
    name: str
    tool: str
    kind: str                  # "normal" (pressing) or "shear" (sliding)
    orientation_deg: float
    insertion_mm: float
    pose_index: int
    trial_index: int = 0       # number of this trial among the same tool, pose and kind
    session_index: int = 0     # position in the recording session (sets the host clock)


def _group(params: dict) -> dict:
    try:
        sim = params["simulate_tool"]
    except (KeyError, TypeError):
        raise ConfigError("params: the simulate_tool group is missing") from None
    return {k: v for k, v in sim.items() if k != "scales"}


def session_plan(params: dict) -> list[TrialSpec]:
    """All trials of a simulated session in recording order: per tool, per pose, normal then shear."""
    sim = _group(params)
    poses = sim["poses"]
    if sim["poses_per_tool"] > len(poses):
        raise ConfigError(f"simulate_tool.poses_per_tool={sim['poses_per_tool']} exceeds the "
                          f"{len(poses)} poses listed in simulate_tool.poses")
    specs: list[TrialSpec] = []
    for tool in sim["tools_used"]:
        if tool not in sim["tools"]:
            raise ConfigError(f"simulate_tool.tools_used: unknown tool '{tool}' "
                              f"(known: {sorted(sim['tools'])})")
        for p in range(sim["poses_per_tool"]):
            pose = poses[p]
            for kind, count in (("normal", sim["normal_trials_per_pose"]),
                                ("shear", sim["shear_trials_per_pose"])):
                for k in range(count):
                    specs.append(TrialSpec(f"{tool}_p{p:02d}_{kind}{k:02d}", tool, kind,
                                           float(pose["orientation_deg"]), float(pose["insertion_mm"]),
                                           p, k, len(specs)))
    return specs


def frames_per_trial(params: dict, kind: str) -> int:
    """Camera frames of a pressing ("normal") or sliding ("shear") trial."""
    sim = _group(params)
    return int(sim["frames_per_trial"] if kind == "normal" else sim["shear_frames_per_trial"])


def _trial_rng(seed: int, spec: TrialSpec, sub: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(
        [seed, STREAM_TRIAL, zlib.crc32(spec.tool.encode()), spec.pose_index, spec.trial_index,
         KINDS.index(spec.kind), sub]))


def _uniform(rng: np.random.Generator, bounds) -> float:
    lo, hi = bounds
    return float(rng.uniform(lo, hi))


# --- calibration and rig constants --------------------------------------------------------------

def calibration_matrix(params: dict) -> np.ndarray:
    """The session's 6x6 Nano17 calibration (N or N*mm per volt): diagonal-dominant, small cross-talk."""
    cal = _group(params)["calibration"]
    rng = np.random.default_rng(np.random.SeedSequence([params["seed"], STREAM_CAL]))
    full = np.array(list(cal["full_scale_n"]) + list(cal["full_scale_nmm"]), float)
    diag = full / cal["full_scale_v"] * (1 + cal["gain_rel_std"] * rng.standard_normal(6))
    off = cal["crosstalk_rel"] * rng.standard_normal((6, 6)) * diag[:, None]
    np.fill_diagonal(off, 0.0)
    return np.diag(diag) + off


def write_session_calibration(session_dir: str | Path, params: dict) -> None:
    """nano17.cal of the session (the same matrix write_trial encodes the forces with)."""
    layout.write_calibration(Path(session_dir) / "nano17.cal", calibration_matrix(params),
                             serial=f"FT-SIM-{params['seed'] % 10000:04d}")


def _rig(params: dict) -> dict:
    """Per-session constants of the two DIGITs and the logger (drawn once per seed)."""
    sim = _group(params)
    rng = np.random.default_rng(np.random.SeedSequence([params["seed"], STREAM_RIG]))
    cam, nano, grasp = sim["camera"], sim["nano17"], sim["grasp"]
    lsb = layout.ADC_VOLTS / layout.ADC_COUNTS
    return {
        "fps": cam["fps"] * (1 + cam["fps_rel_error"] * rng.standard_normal(2)),
        "latency_s": rng.uniform(*cam["latency_s"], 2),
        "e_star": grasp["e_star_mpa"] * (1 + grasp["e_star_sensor_rel_std"] * rng.standard_normal(2)),
        "gauge_bias_v": nano["gauge_bias_counts"] * lsb * rng.standard_normal(6),
        "drift_period_s": rng.uniform(*sim["render"]["drift_period_s"], (2, 3)),
        "drift_phase": rng.uniform(0, 2 * np.pi, (2, 3)),
    }


def _grid(sim: dict) -> dr.Grid:
    r = sim["render"]
    return dr.Grid(px_per_mm=float(r["px_per_mm"]), down=int(r["height_downsample"]))


def _looks(params: dict, grid: dr.Grid) -> list[dr.DigitLook]:
    sim = _group(params)
    return [dr.make_look(np.random.default_rng(np.random.SeedSequence([params["seed"], STREAM_LOOK, s])),
                         sim["render"], grid) for s in range(2)]


# --- force profiles -----------------------------------------------------------------------------

def _mj(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x ** 3 * (10 - 15 * x + 6 * x ** 2)


def _mj_rate(x: np.ndarray) -> np.ndarray:
    inside = (x >= 0) & (x <= 1)
    return np.where(inside, 30 * x ** 2 * (1 - x) ** 2, 0.0)


class _PressProfile:
    """Normal trial: pressing cycles from 0 N with rests between them (trial time tau, s)."""

    def __init__(self, rng: np.random.Generator, press: dict, duration: float):
        self.presses = []
        tau = min(_uniform(rng, press["rest_start_s"]), 0.25 * duration)
        tau = max(tau, 0.3)
        lo, hi = press["peak_force_n"]
        a, b = press["peak_beta"]
        while True:
            rise, hold, fall = (_uniform(rng, press["rise_s"]), _uniform(rng, press["hold_s"]),
                                _uniform(rng, press["fall_s"]))
            peak = lo + (hi - lo) * float(rng.beta(a, b))
            rest = _uniform(rng, press["rest_s"])
            room = duration - 0.15 - tau
            total = rise + hold + fall
            if total > room:
                if self.presses or room < 0.6:
                    break
                f = room / total           # a very short trial still gets one (faster) press
                rise, hold, fall = rise * f, hold * f, fall * f
            self.presses.append((tau, rise, hold, fall, peak))
            tau += rise + hold + fall + rest
        self.tremor = [(rng.uniform(1.5, 8.0), rng.uniform(0, 2 * np.pi), rng.uniform(0.5, 1.0))
                       for _ in range(4)]
        self.tremor_rel = press["tremor_rel"]

    def normal(self, tau: np.ndarray) -> np.ndarray:
        f = np.zeros_like(tau, dtype=float)
        for t0, rise, hold, fall, peak in self.presses:
            f += peak * (_mj((tau - t0) / rise) - _mj((tau - t0 - rise - hold) / fall))
        ripple = sum(a * np.sin(2 * np.pi * fr * tau + ph) for fr, ph, a in self.tremor) / 2.0
        return np.clip(f * (1 + self.tremor_rel * ripple), 0.0, None)


class _SlideProfile:
    """Shear trial: load the tip, slide it back and forth along an axis (with a spread), unload."""

    def __init__(self, rng: np.random.Generator, slide: dict, duration: float):
        self.load = _uniform(rng, slide["normal_load_n"])
        self.mu = _uniform(rng, slide["tip_friction"])
        self.ramp = min(slide["ramp_s"], 0.15 * duration)
        self.t_on = max(min(0.6, 0.2 * duration), 0.3)
        self.t_off = duration - 0.15 - self.ramp
        self.v0 = slide["slide_v0_mm_s"]
        self.ripple_rel = slide["load_ripple_rel"]
        self.ripple = (rng.uniform(0.3, 1.0), rng.uniform(0, 2 * np.pi))
        self.strokes = []
        tau = self.t_on + self.ramp + 0.1
        axis, spread = np.deg2rad(slide["stroke_axis_deg"]), np.deg2rad(slide["stroke_spread_deg"])
        way = rng.choice([0.0, np.pi])                  # the first stroke goes either way, then back and forth
        while True:
            dur = _uniform(rng, slide["stroke_s"])
            dist = _uniform(rng, slide["stroke_mm"])
            ang = axis + way + spread * rng.standard_normal()
            way = np.pi - way
            pause = _uniform(rng, slide["pause_s"])
            room = self.t_off - 0.05 - tau
            if dur > room:
                if self.strokes or room < 0.3:
                    break
                dur = room
            self.strokes.append((tau, dur, dist * np.array([np.cos(ang), np.sin(ang)])))
            tau += dur + pause

    def normal(self, tau: np.ndarray) -> np.ndarray:
        env = _mj((tau - self.t_on) / self.ramp) - _mj((tau - self.t_off) / self.ramp)
        rip = 1 + self.ripple_rel * np.sin(2 * np.pi * self.ripple[0] * tau + self.ripple[1])
        return np.clip(self.load * env * rip, 0.0, None)

    def tip_motion(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tip position (n, u) in mm and velocity in mm/s."""
        pos = np.zeros((len(tau), 2))
        vel = np.zeros((len(tau), 2))
        for t0, dur, delta in self.strokes:
            x = (tau - t0) / dur
            pos += _mj(x)[:, None] * delta
            vel += (_mj_rate(x) / dur)[:, None] * delta
        return pos, vel


# --- mechanics ----------------------------------------------------------------------------------

def _segment_in_rect(p0: np.ndarray, a: np.ndarray, half_w: float, half_h: float) -> tuple[float, float]:
    """[s_lo, s_hi] (s >= 0) of the ray p0 + s a inside the gel rectangle |u| <= half_w, |z| <= half_h."""
    lo, hi = 0.0, np.inf
    for i, half in enumerate((half_w, half_h)):
        if abs(a[i]) < 1e-12:
            if abs(p0[i]) > half:
                return 0.0, 0.0
            continue
        t1, t2 = (-half - p0[i]) / a[i], (half - p0[i]) / a[i]
        lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
    return lo, max(lo, hi)


def _skew(p: np.ndarray) -> np.ndarray:
    return np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])


class _Grasp:
    """Contact lines, stiffness and lever arms of one trial's grasp."""

    def __init__(self, spec: TrialSpec, sim: dict, rig: dict, rng: np.random.Generator, grid: dr.Grid):
        g = sim["grasp"]
        tool = sim["tools"][spec.tool]
        pose = sim["poses"][spec.pose_index] if spec.pose_index < len(sim["poses"]) else {}
        self.theta = np.deg2rad(spec.orientation_deg + g["orientation_jitter_deg"] * rng.standard_normal())
        self.insertion = spec.insertion_mm + g["insertion_jitter_mm"] * rng.standard_normal()
        self.lean = np.deg2rad(pose.get("lean_deg", 0.0) + g["lean_jitter_deg"] * rng.standard_normal())
        lateral = pose.get("lateral_mm", 0.0) + g["lateral_jitter_mm"] * rng.standard_normal()
        self.preload = g["grip_force_n"] * (1 + g["grip_force_rel_std"] * rng.standard_normal())
        self.pin = _uniform(rng, g["tip_pin_fraction"])
        self.roll = float(rng.uniform(0, 2 * np.pi))
        self.mu_pad = g["pad_friction"]
        self.mass = tool["mass_g"] / 1000.0

        # contact line on the pad (u, z mm; origin at the gel centre, fingertip edge at z = -half_h)
        self.axis = np.array([np.sin(self.theta), -np.cos(self.theta)])
        self.butt = np.array([lateral, -grid.half_height_mm]) - self.insertion * self.axis
        s_lo, s_hi = _segment_in_rect(self.butt, self.axis, grid.half_width_mm, grid.half_height_mm)
        if s_hi - s_lo < 3.0:
            raise ConfigError(f"simulate_tool: pose {spec.pose_index} of trial {spec.name} puts less "
                              f"than 3 mm of handle on the gel (orientation {spec.orientation_deg} deg, "
                              f"insertion {spec.insertion_mm} mm)")
        k = int(g["line_samples"])
        self.ds = (s_hi - s_lo) / k
        self.s_k = s_lo + (np.arange(k) + 0.5) * self.ds
        self.length = s_hi - s_lo
        centre = self.butt + 0.5 * (s_lo + s_hi) * self.axis
        pts_uz = self.butt[None, :] + self.s_k[:, None] * self.axis[None, :] - centre[None, :]
        rh = tool["half_thickness_mm"]
        # spring points of the left (n = -rh) and right (n = +rh) pads, about the grasp centre
        self.points = [np.column_stack([np.full(k, side * rh), pts_uz]) for side in (-1.0, 1.0)]
        self.k_n = np.pi * rig["e_star"] / 2 * self.ds               # N/mm per spring, per pad
        self.k_t = g["shear_stiffness_n_per_mm2"] * rig["e_star"] / g["e_star_mpa"] * self.ds
        self.depth0 = self.preload / (np.pi * rig["e_star"] / 2 * self.length)   # mm, per pad
        self.jac = [np.stack([np.hstack([np.eye(3), -_skew(p)]) for p in pts]) for pts in self.points]
        K = np.zeros((6, 6))
        for pad in range(2):
            kd = np.diag([self.k_n[pad], self.k_t[pad], self.k_t[pad]])
            for J in self.jac[pad]:
                K += J.T @ kd @ J
        # the gel around each contact resists twisting about the finger normal as well
        K[3, 3] += 2 * g["torsion_stiffness_nmm_per_rad"] * rig["e_star"].mean() / g["e_star_mpa"]
        self.K_inv = np.linalg.inv(K)

        # lever arms: tip and centre of mass relative to the grasp centre (n, u, z)
        a3 = np.array([np.sin(self.lean), np.sin(self.theta) * np.cos(self.lean),
                       -np.cos(self.theta) * np.cos(self.lean)])
        butt3 = np.array([0.0, self.butt[0] - centre[0], self.butt[1] - centre[1]])
        self.r_tip = butt3 + tool["length_mm"] * a3 + np.array([tool["tip_offset_mm"], 0.0, 0.0])
        self.r_cg = butt3 + tool["cg_from_butt_mm"] * a3

    def pinned_reaction(self, normal: np.ndarray, mu_tip: float) -> np.ndarray:
        """(T, 3) reaction on the tool tip for a stuck tip pressed with ``normal`` (N)."""
        lever = self.r_tip[:2] / abs(self.r_tip[2])
        lat = -self.pin * normal[:, None] * lever[None, :]
        mag = np.linalg.norm(lat, axis=1)
        cap = mu_tip * normal
        scale = np.where(mag > cap, cap / np.maximum(mag, 1e-12), 1.0)
        return np.column_stack([lat * scale[:, None], normal])

    def pads(self, reaction: np.ndarray) -> dict:
        """Per-pad line depths and tangential displacements for tip reactions (T, 3) in N."""
        weight = np.array([0.0, 0.0, -self.mass * G])
        force = reaction + weight
        moment = np.cross(self.r_tip, reaction) + np.cross(self.r_cg, weight)
        q = np.column_stack([force, moment]) @ self.K_inv.T                  # (T, 6)
        out = {"depth": [], "du": [], "dz": [], "normal_n": [], "shear_n": []}
        for pad, side in enumerate((-1.0, 1.0)):
            d = np.einsum("kij,tj->tki", self.jac[pad], q)                      # (T, K, 3)
            depth = self.depth0[pad] - side * d[..., 0]
            out["depth"].append(depth)
            out["du"].append(d[..., 1])
            out["dz"].append(d[..., 2])
            out["normal_n"].append(self.k_n[pad] * np.clip(depth, 0, None).sum(axis=1))
            out["shear_n"].append(self.k_t[pad] * np.hypot(d[..., 1].sum(axis=1), d[..., 2].sum(axis=1)))
        for key in out:
            out[key] = np.stack(out[key], axis=1)                                # (T, 2, ...)
        out["traction_ratio"] = out["shear_n"] / (self.mu_pad * np.maximum(out["normal_n"], 1e-9))
        out["q"] = q
        return out


# --- one trial ----------------------------------------------------------------------------------

class _Trial:
    """Everything about one simulated trial; frames are rendered on demand (streamed to disk)."""

    def __init__(self, spec: TrialSpec, params: dict, noise: bool = True):
        if spec.kind not in KINDS:
            raise ConfigError(f"trial {spec.name}: kind '{spec.kind}' must be normal or shear")
        self.spec, self.params = spec, params
        sim = self.sim = _group(params)
        seed = params["seed"]
        if spec.tool not in sim["tools"]:
            raise ConfigError(f"trial {spec.name}: unknown tool '{spec.tool}'")
        self.rig = _rig(params)
        self.grid = _grid(sim)
        rng = _trial_rng(seed, spec, 0)
        self.grasp = _Grasp(spec, sim, self.rig, rng, self.grid)
        cam = sim["camera"]
        self.n_frames = frames_per_trial(params, spec.kind)
        self.duration = self.n_frames / cam["fps"]
        self.t0_ns = int(round((SESSION_EPOCH_S + spec.session_index * sim["trial_spacing_s"]) * 1e9))
        if spec.kind == "normal":
            self.profile = _PressProfile(rng, sim["press"], self.duration)
            self.mu_tip = float(np.mean(sim["slide"]["tip_friction"]))
        else:
            self.profile = _SlideProfile(rng, sim["slide"], self.duration)
            self.mu_tip = self.profile.mu
        nano = sim["nano17"]
        ang = rng.uniform(0, 2 * np.pi)
        self.contact_point = np.array([np.cos(ang), np.sin(ang), 0.0]) * rng.uniform(0, nano["contact_offset_mm"])
        self.contact_point[2] = nano["cap_height_mm"]

        # camera stamps per sensor (host ns) and exposure times (trial s)
        self.host_ns, self.exposure = [], []
        for s in range(2):
            r = _trial_rng(seed, spec, 10 + s)
            period_ns = 1e9 / self.rig["fps"][s]
            t = r.uniform(0, period_ns) + period_ns * np.arange(self.n_frames)
            jitter = cam["stamp_jitter_ms"] * 1e6 * r.standard_normal(self.n_frames)
            t += np.clip(jitter, -0.4 * period_ns, 0.4 * period_ns)     # stamps stay in order
            self.host_ns.append(self.t0_ns + np.rint(t).astype(np.int64))
            self.exposure.append((self.host_ns[s] - self.t0_ns) / 1e9 - self.rig["latency_s"][s])

        self.noise = noise
        self.pad_state = [self.grasp.pads(self.reaction(self.exposure[s])) for s in range(2)]
        self._contacts = self._renderers = None

    def _build_renderers(self) -> None:
        """Contact geometry and renderers of both sensors (built on the first frame)."""
        spec, sim, seed = self.spec, self.sim, self.params["seed"]
        looks = _looks(self.params, self.grid)
        tool = sim["tools"][spec.tool]
        profile = dr.HandleProfile(radius_mm=tool["handle_radius_mm"], flat_width_mm=tool["flat_width_mm"],
                                   end_radius_mm=tool["end_radius_mm"], texture=tool["texture"],
                                   texture_period_mm=tool["texture_period_mm"],
                                   texture_depth_mm=tool["texture_depth_mm"])
        contacts, renderers = [], []
        for s in range(2):
            # the two pads touch opposite sides of the handle: their own stretch of its texture
            roll = self.grasp.roll + np.pi * s
            contacts.append(dr.LineContact(self.grid, s == 1, self.grasp.butt, self.grasp.axis,
                                           self.grasp.s_k, profile, roll, _trial_rng(seed, spec, 20 + s),
                                           drag_sigma_mm=sim["render"]["shear_spread_mm"]))
            look = looks[s] if self.noise else dr.DigitLook(**{**looks[s].__dict__, "noise_std": 0.0})
            renderers.append(dr.Renderer(look, self.grid, sim["render"], _trial_rng(seed, spec, 30 + s)))
        self._contacts, self._renderers = contacts, renderers

    @property
    def contacts(self) -> list[dr.LineContact]:
        if self._contacts is None:
            self._build_renderers()
        return self._contacts

    @property
    def renderers(self) -> list[dr.Renderer]:
        if self._renderers is None:
            self._build_renderers()
        return self._renderers

    # ground truth ------------------------------------------------------------------------------
    def reaction(self, tau: np.ndarray) -> np.ndarray:
        """Force of the Nano17 on the tool tip (T, 3) N, gripper frame (n, u, z)."""
        tau = np.asarray(tau, float)
        normal = self.profile.normal(tau)
        if self.spec.kind == "normal":
            return self.grasp.pinned_reaction(normal, self.mu_tip)
        _, vel = self.profile.tip_motion(tau)
        speed = np.linalg.norm(vel, axis=1)
        direction = vel / np.maximum(speed, 1e-12)[:, None]
        # regularised stick-slip: standing still (loading, pauses, unloading) static friction pins
        # the tip as in a press; sliding, kinetic friction opposes the velocity. Both are bounded
        # by mu F_N, and so is the blend.
        slip = np.tanh(speed / self.profile.v0)[:, None]
        stuck = self.grasp.pinned_reaction(normal, self.mu_tip)[:, :2]
        lat = (1 - slip) * stuck - slip * self.mu_tip * normal[:, None] * direction
        return np.column_stack([lat, normal])

    def sensor_wrench(self, tau: np.ndarray) -> np.ndarray:
        """What the Nano17 reads (T, 6): Fx, Fy, Fz in N, Tx, Ty, Tz in N*mm, in its own frame
        (mount upright: x = n, y = u, z up, so a press reads Fz < 0 as on a real ATI sensor)."""
        tau = np.asarray(tau, float)
        force = -self.reaction(tau)
        point = np.broadcast_to(self.contact_point, force.shape).copy()
        if self.spec.kind == "shear":
            pos, _ = self.profile.tip_motion(tau)
            point[:, :2] += pos
        wrench = np.column_stack([force, np.cross(point, force)])
        mount = self.sim["nano17"]["mount"]
        if mount == "inverted":          # turned over (180 deg about x): a press reads Fz > 0
            wrench *= np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0])
        elif mount != "upright":
            raise ConfigError(f"simulate_tool.nano17.mount '{mount}' must be upright or inverted")
        return wrench

    # frames --------------------------------------------------------------------------------------
    def _frame_rng(self, sensor: int, index: int) -> np.random.Generator:
        return _trial_rng(self.params["seed"], self.spec, 1000 + 100000 * sensor + index)

    def frame(self, sensor: int, index: int) -> np.ndarray:
        st = self.pad_state[sensor]
        contact = self.contacts[sensor]
        h = contact.height(st["depth"][index, sensor])
        disp = contact.displacement(st["du"][index, sensor], st["dz"][index, sensor])
        if not self.noise:
            return self.renderers[sensor].render(h, disp)
        rng = self._frame_rng(sensor, index)
        r = self.sim["render"]
        gain = (1 + r["led_gain_jitter"] * rng.standard_normal(3)).astype(np.float32)
        t_sess = (self.host_ns[sensor][index] / 1e9 - SESSION_EPOCH_S)
        offset = (r["warmup_dn"] * (1 - np.exp(-t_sess / r["warmup_tau_s"]))
                  + r["drift_dn"] * np.sin(2 * np.pi * t_sess / self.rig["drift_period_s"][sensor]
                                           + self.rig["drift_phase"][sensor]))
        return self.renderers[sensor].render(h, disp, gain, offset.astype(np.float32), rng)

    def no_grasp_frame(self, sensor: int) -> np.ndarray:
        """The sensor with the gripper open (no handle on the gel), noise-free."""
        return self.renderers[sensor].render(None)

    def frames_csv(self, sensor: int) -> str:
        rows = ["frame,host_ns"] + [f"{i},{t}" for i, t in enumerate(self.host_ns[sensor])]
        return "\n".join(rows) + "\n"

    # Arduino log --------------------------------------------------------------------------------
    def serial(self, quiet: bool = False) -> dict:
        """The Arduino's log: lines, counts, stamps, and the truth at each sample (for tests)."""
        nano = self.sim["nano17"]
        rng = _trial_rng(self.params["seed"], self.spec, 40)
        start_host_ns = self.t0_ns - int(round(nano["preroll_s"] * 1e9))
        offset_s = _uniform(rng, nano["clock_offset_s"])
        ppm = nano["rate_error_ppm"] * rng.standard_normal()
        period_ms = 1000.0 / nano["serial_hz"]
        end_s = nano["preroll_s"] + self.duration + nano["postroll_s"]
        n = int((end_s - offset_s) * 1000.0 / period_ms)
        a_first = rng.uniform(5.0, 40.0)
        loop = a_first + period_ms * np.arange(n) + rng.uniform(0, 1.0, n)
        stamp_ms = np.floor(loop).astype(np.int64)
        delay = np.abs(rng.standard_normal(n)) * nano["jitter_ms"]
        sample_ms = loop + (0.0 if quiet else delay)
        host_ns = start_host_ns + offset_s * 1e9 + sample_ms * 1e6 / (1 + ppm * 1e-6)
        tau = (host_ns - self.t0_ns) / 1e9
        wrench = self.sensor_wrench(tau)
        C = calibration_matrix(self.params)
        bias = self.rig["gauge_bias_v"] + (0.0 if quiet else nano["gauge_bias_drift_counts"]
                                           * layout.ADC_VOLTS / layout.ADC_COUNTS * rng.standard_normal(6))
        volts = wrench @ np.linalg.inv(C).T + bias
        raw = (volts + layout.ADC_ZERO_V) * layout.ADC_COUNTS / layout.ADC_VOLTS
        noise = rng.standard_normal(raw.shape) * (0.0 if quiet else nano["adc_noise_counts"])
        counts = np.clip(np.rint(raw + noise), 0, layout.ADC_COUNTS).astype(np.int64)
        lines = [f"# start_host_ns={start_host_ns}"]
        lines += [f"{ms}," + ",".join(str(c) for c in row) for ms, row in zip(stamp_ms, counts)]
        return {"lines": lines, "arduino_ms": stamp_ms, "counts": counts, "start_host_ns": start_host_ns,
                "offset_s": offset_s, "rate_ppm": ppm, "sample_host_ns": np.rint(host_ns).astype(np.int64),
                "stamp_host_ns": np.rint(start_host_ns + offset_s * 1e9
                                         + stamp_ms * 1e6 / (1 + ppm * 1e-6)).astype(np.int64),
                "wrench": wrench, "clipped": int(((counts == 0) | (counts == layout.ADC_COUNTS)).sum())}

    def meta(self) -> layout.TrialMeta:
        return layout.TrialMeta(trial=self.spec.name, tool=self.spec.tool, kind=self.spec.kind,
                                orientation_deg=self.spec.orientation_deg, insertion_mm=self.spec.insertion_mm,
                                camera_fps=float(self.sim["camera"]["fps"]),
                                serial_hz=float(self.sim["nano17"]["serial_hz"]),
                                notes={"source": "simulated"})


# --- public API ---------------------------------------------------------------------------------

def simulate_trial(spec: TrialSpec, params: dict, quiet: bool = False) -> dict:
    """Simulate one trial in memory (for tests): frames, stamps, truth and the Arduino log.

    quiet=True switches off camera noise, flicker, drift, ADC noise, sampling jitter and bias
    drift (the physics stays), so exact checks are possible.
    """
    trial = _Trial(spec, params, noise=not quiet)
    frames = {name: np.stack([trial.frame(s, i) for i in range(trial.n_frames)])
              for s, name in enumerate(layout.SENSORS)}
    ser = trial.serial(quiet=quiet)
    tau = np.arange(-trial.sim["nano17"]["preroll_s"],
                    trial.duration + trial.sim["nano17"]["postroll_s"], 1.0 / TRUTH_RATE_HZ)
    wrench = trial.sensor_wrench(tau)
    return {
        "spec": spec,
        "meta": trial.meta(),
        "frames": frames,
        "host_ns": {name: trial.host_ns[s] for s, name in enumerate(layout.SENSORS)},
        "frame_wrench": {name: trial.sensor_wrench(trial.exposure[s]) for s, name in enumerate(layout.SENSORS)},
        "no_grasp": {name: trial.no_grasp_frame(s) for s, name in enumerate(layout.SENSORS)},
        "truth": {"host_ns": trial.t0_ns + np.rint(tau * 1e9).astype(np.int64), "wrench": wrench,
                  "normal_n": np.abs(wrench[:, 2]), "shear_n": np.hypot(wrench[:, 0], wrench[:, 1])},
        "serial": ser,
        "serial_lines": ser["lines"],
        "calibration": calibration_matrix(params),
        "pads": {name: {k: v[:, s] for k, v in trial.pad_state[s].items() if k != "q"}
                 for s, name in enumerate(layout.SENSORS)},
        "max_traction_ratio": float(max(st["traction_ratio"].max() for st in trial.pad_state)),
        "t0_ns": trial.t0_ns,
    }


def trial_mechanics(spec: TrialSpec, params: dict) -> dict:
    """The trial's forces and pad loads at every frame, without rendering (cheap checks).

    Returns frame_wrench (sensor -> (n, 6) Nano17 reading at each exposure), pads (sensor ->
    per-frame pad state) and max_traction_ratio (the largest |T| / (mu N) of either pad).
    """
    trial = _Trial(spec, params)
    return {"frame_wrench": {name: trial.sensor_wrench(trial.exposure[s]) for s, name in enumerate(layout.SENSORS)},
            "pads": {name: {k: v[:, s] for k, v in trial.pad_state[s].items() if k != "q"}
                     for s, name in enumerate(layout.SENSORS)},
            "max_traction_ratio": float(max(st["traction_ratio"].max() for st in trial.pad_state))}


def _write_png(path: Path, img: np.ndarray) -> None:
    ok, buf = cv2.imencode(".png", img)
    if not ok:
        raise RuntimeError(f"PNG encoding failed for {path}")
    with atomic_path(path) as tmp:
        tmp.write_bytes(buf.tobytes())


def write_trial(session_dir: str | Path, spec: TrialSpec, params: dict) -> None:
    """Write one trial folder in the rig's layout (layout.py), every file atomically."""
    trial = _Trial(spec, params)
    tdir = Path(session_dir) / spec.name
    for s, name in enumerate(layout.SENSORS):
        sdir = tdir / name
        sdir.mkdir(parents=True, exist_ok=True)
        frame_names = [layout.FRAME_NAME.format(i) for i in range(trial.n_frames)]
        for i, frame_name in enumerate(frame_names):
            _write_png(sdir / frame_name, trial.frame(s, i))
        # a re-simulation with fewer frames per trial must not leave the old run's later frames
        # behind: they are not in frames.csv, but DVC would version them and they waste the disk
        for stale in set(q.name for q in sdir.glob("frame_*.png")) - set(frame_names):
            (sdir / stale).unlink()
        write_text(sdir / "frames.csv", trial.frames_csv(s))
    write_text(tdir / "force.log", "\n".join(trial.serial()["lines"]) + "\n")
    trial.meta().write(tdir)


def write_session(session_dir: str | Path, params: dict, trials: list[str] | None = None) -> list[TrialSpec]:
    """nano17.cal and every trial of the plan (or only the named ones) into ``session_dir``."""
    plan = session_plan(params)
    if trials is not None:
        plan = [s for s in plan if s.name in set(trials)]
    write_session_calibration(session_dir, params)
    for spec in plan:
        write_trial(session_dir, spec, params)
    return plan


def render_at_forces(spec: TrialSpec, params: dict, normal_n, reaction_n=None, noise: bool = False) -> dict:
    """Frames of both sensors at the trial's grasp for given tip loads (tests and figures).

    normal_n: tip normal forces (N), the tip pinned as in a pressing trial; or reaction_n: (T, 3)
    reactions on the tip in the gripper frame (n, u, z). Index 0 of the result is not special:
    the zero-force reference is the frame for 0 N.
    """
    trial = _Trial(spec, params, noise=noise)
    if reaction_n is None:
        reaction_n = trial.grasp.pinned_reaction(np.asarray(normal_n, float), trial.mu_tip)
    state = trial.grasp.pads(np.asarray(reaction_n, float))
    out = {"pads": state, "no_grasp": {}}
    for s, name in enumerate(layout.SENSORS):
        c, r = trial.contacts[s], trial.renderers[s]
        frames = []
        for i in range(len(reaction_n)):
            h = c.height(state["depth"][i, s])
            disp = c.displacement(state["du"][i, s], state["dz"][i, s])
            frames.append(r.render(h, disp, rng=trial._frame_rng(s, i) if noise else None))
        out[name] = np.stack(frames)
        out["no_grasp"][name] = trial.no_grasp_frame(s)
    out["gel_height"] = {name: trial.renderers[s].gel_height(trial.contacts[s].height(state["depth"][-1, s]))
                         for s, name in enumerate(layout.SENSORS)}
    return out


def simulate_public_session(root: str | Path, params: dict, seed: int | None = None,
                            n_trials: int | None = None) -> list[str]:
    """Write simulated trials in the public dataset's layout (data_normal/, data_shear/).

    Frames at 15 FPS (every ``public.frame_stride``-th camera frame), each paired with the force
    at its exposure: normal trials as the public rig's raw Arduino count of the normal force,
    shear trials as fx,fy,fz in N. Returns the trial folder names written.
    """
    from tactilepipe.tool.formats import public_layout as pl
    if seed is not None:
        params = {**params, "seed": int(seed)}
    stride = int(_group(params)["public"]["frame_stride"])
    plan = session_plan(params)[:n_trials]
    names = []
    for spec in plan:
        trial = _Trial(spec, params)
        idx = np.arange(0, trial.n_frames, stride)
        left = [trial.frame(0, i) for i in idx]
        right = [trial.frame(1, i) for i in idx]
        wrench = trial.sensor_wrench(trial.exposure[0][idx])
        noise = _trial_rng(params["seed"], spec, 50).standard_normal((len(idx), 3)) * 0.02
        if spec.kind == "normal":
            forces = np.abs(wrench[:, 2]) + noise[:, 2]
        else:
            forces = wrench[:, :3] + noise
        pl.write_public_trial(root, spec.name, left, right, forces, spec.kind)
        names.append(spec.name)
    # the tools and poses, which the layout itself does not record (tool/formats/trials.py)
    from tactilepipe.core.atomic import write_text
    rows = ["trial,tool,orientation_deg,insertion_mm"] + [
        f"{s.name},{s.tool},{s.orientation_deg:g},{s.insertion_mm:g}" for s in plan]
    write_text(Path(root) / "trials.csv", "\n".join(rows) + "\n")
    return names


def benchmark_render(n_frames: int = 300, params: dict | None = None) -> float:
    """Rendered QVGA frames per second on one core (height field, shear, shading, noise; no PNG)."""
    import time
    if params is None:
        params = default_params()
    spec = session_plan(params)[0]
    trial = _Trial(spec, params)
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        trial.frame(0, 0)
        t = time.perf_counter()
        for i in range(n_frames):
            trial.frame(i % 2, i % trial.n_frames)
        return n_frames / (time.perf_counter() - t)
    finally:
        cv2.setNumThreads(threads)


def default_params() -> dict:
    """params.yaml at its own scale (the simulator's group and the seed)."""
    from tactilepipe.core.config import load_params
    return load_params()
