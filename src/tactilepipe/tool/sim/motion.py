"""Mechanics of a simulated trial: the tip-force profiles (pressing, sliding) and the grasp (the tool
as a rigid body on the two gel pads). The physics is described in trial.py."""

from __future__ import annotations

import numpy as np

from tactilepipe.core.errors import ConfigError
from tactilepipe.tool.sim.plan import G, TrialSpec, uniform
from tactilepipe.tool.sim.render import Grid


def min_jerk(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x ** 3 * (10 - 15 * x + 6 * x ** 2)


def min_jerk_rate(x: np.ndarray) -> np.ndarray:
    inside = (x >= 0) & (x <= 1)
    return np.where(inside, 30 * x ** 2 * (1 - x) ** 2, 0.0)


class PressProfile:
    """Normal trial: pressing cycles from 0 N with rests between them (trial time tau, s)."""

    def __init__(self, rng: np.random.Generator, press: dict, duration: float):
        self.presses = []
        tau = min(uniform(rng, press["rest_start_s"]), 0.25 * duration)
        tau = max(tau, 0.3)
        lo, hi = press["peak_force_n"]
        a, b = press["peak_beta"]
        while True:
            rise, hold, fall = (uniform(rng, press["rise_s"]), uniform(rng, press["hold_s"]),
                                uniform(rng, press["fall_s"]))
            peak = lo + (hi - lo) * float(rng.beta(a, b))
            rest = uniform(rng, press["rest_s"])
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
            f += peak * (min_jerk((tau - t0) / rise) - min_jerk((tau - t0 - rise - hold) / fall))
        ripple = sum(a * np.sin(2 * np.pi * fr * tau + ph) for fr, ph, a in self.tremor) / 2.0
        return np.clip(f * (1 + self.tremor_rel * ripple), 0.0, None)


class SlideProfile:
    """Shear trial: load the tip, slide it back and forth along an axis (with a spread), unload."""

    def __init__(self, rng: np.random.Generator, slide: dict, duration: float):
        self.load = uniform(rng, slide["normal_load_n"])
        self.mu = uniform(rng, slide["tip_friction"])
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
            dur = uniform(rng, slide["stroke_s"])
            dist = uniform(rng, slide["stroke_mm"])
            ang = axis + way + spread * rng.standard_normal()
            way = np.pi - way
            pause = uniform(rng, slide["pause_s"])
            room = self.t_off - 0.05 - tau
            if dur > room:
                if self.strokes or room < 0.3:
                    break
                dur = room
            self.strokes.append((tau, dur, dist * np.array([np.cos(ang), np.sin(ang)])))
            tau += dur + pause

    def normal(self, tau: np.ndarray) -> np.ndarray:
        env = min_jerk((tau - self.t_on) / self.ramp) - min_jerk((tau - self.t_off) / self.ramp)
        rip = 1 + self.ripple_rel * np.sin(2 * np.pi * self.ripple[0] * tau + self.ripple[1])
        return np.clip(self.load * env * rip, 0.0, None)

    def tip_motion(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tip position (n, u) in mm and velocity in mm/s."""
        pos = np.zeros((len(tau), 2))
        vel = np.zeros((len(tau), 2))
        for t0, dur, delta in self.strokes:
            x = (tau - t0) / dur
            pos += min_jerk(x)[:, None] * delta
            vel += (min_jerk_rate(x) / dur)[:, None] * delta
        return pos, vel


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


class Grasp:
    """Contact lines, stiffness and lever arms of one trial's grasp."""

    def __init__(self, spec: TrialSpec, sim: dict, rig: dict, rng: np.random.Generator, grid: Grid):
        g = sim["grasp"]
        tool = sim["tools"][spec.tool]
        pose = sim["poses"][spec.pose_index] if spec.pose_index < len(sim["poses"]) else {}
        self.theta = np.deg2rad(spec.orientation_deg + g["orientation_jitter_deg"] * rng.standard_normal())
        self.insertion = spec.insertion_mm + g["insertion_jitter_mm"] * rng.standard_normal()
        self.lean = np.deg2rad(pose.get("lean_deg", 0.0) + g["lean_jitter_deg"] * rng.standard_normal())
        lateral = pose.get("lateral_mm", 0.0) + g["lateral_jitter_mm"] * rng.standard_normal()
        self.preload = g["grip_force_n"] * (1 + g["grip_force_rel_std"] * rng.standard_normal())
        self.pin = uniform(rng, g["tip_pin_fraction"])
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
