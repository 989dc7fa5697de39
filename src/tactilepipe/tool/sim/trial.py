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
  tip's tendency to slide sideways (the moment about the grasp: M = L (F_N sin(theta) - R_x cos(theta))),
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
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from tactilepipe.core.atomic import atomic_path, write_text
from tactilepipe.core.errors import ConfigError
from tactilepipe.tool.formats import native_layout as layout
from tactilepipe.tool.formats.arrival_log import ARRIVAL_NAME
from tactilepipe.tool.sim.motion import Grasp, PressProfile, SlideProfile
from tactilepipe.tool.sim.plan import (KINDS, SESSION_EPOCH_S, STREAM_LOOK, STREAM_RIG, TrialSpec, calibration_matrix,
                                       frames_per_trial, sim_group, trial_rng, uniform)
from tactilepipe.tool.sim.render import DigitLook, Grid, HandleProfile, LineContact, Renderer, make_look

TRUTH_RATE_HZ = 1000.0              # rate of simulate_trial's ground-truth series


def _rig(params: dict) -> dict:
    """Per-session constants of the two DIGITs and the logger (drawn once per seed)."""
    sim = sim_group(params)
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


def _grid(sim: dict) -> Grid:
    r = sim["render"]
    return Grid(px_per_mm=float(r["px_per_mm"]), down=int(r["height_downsample"]))


def _looks(params: dict, grid: Grid) -> list[DigitLook]:
    sim = sim_group(params)
    return [make_look(np.random.default_rng(np.random.SeedSequence([params["seed"], STREAM_LOOK, s])),
                      sim["render"], grid) for s in range(2)]


class Trial:
    """Everything about one simulated trial; frames are rendered on demand (streamed to disk)."""

    def __init__(self, spec: TrialSpec, params: dict, noise: bool = True):
        if spec.kind not in KINDS:
            raise ConfigError(f"trial {spec.name}: kind '{spec.kind}' must be normal or shear")
        self.spec, self.params = spec, params
        sim = self.sim = sim_group(params)
        seed = params["seed"]
        if spec.tool not in sim["tools"]:
            raise ConfigError(f"trial {spec.name}: unknown tool '{spec.tool}'")
        self.rig = _rig(params)
        self.grid = _grid(sim)
        rng = trial_rng(seed, spec, 0)
        self.grasp = Grasp(spec, sim, self.rig, rng, self.grid)
        cam = sim["camera"]
        self.n_frames = frames_per_trial(params, spec.kind)
        self.duration = self.n_frames / cam["fps"]
        self.t0_ns = int(round((SESSION_EPOCH_S + spec.session_index * sim["trial_spacing_s"]) * 1e9))
        if spec.kind == "normal":
            self.profile = PressProfile(rng, sim["press"], self.duration)
            self.mu_tip = float(np.mean(sim["slide"]["tip_friction"]))
        else:
            self.profile = SlideProfile(rng, sim["slide"], self.duration)
            self.mu_tip = self.profile.mu
        nano = sim["nano17"]
        ang = rng.uniform(0, 2 * np.pi)
        self.contact_point = np.array([np.cos(ang), np.sin(ang), 0.0]) * rng.uniform(0, nano["contact_offset_mm"])
        self.contact_point[2] = nano["cap_height_mm"]

        # camera stamps per sensor (host ns) and exposure times (trial s)
        self.host_ns, self.exposure = [], []
        for s in range(2):
            r = trial_rng(seed, spec, 10 + s)
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
        profile = HandleProfile(radius_mm=tool["handle_radius_mm"], flat_width_mm=tool["flat_width_mm"],
                                end_radius_mm=tool["end_radius_mm"], texture=tool["texture"],
                                texture_period_mm=tool["texture_period_mm"],
                                texture_depth_mm=tool["texture_depth_mm"])
        contacts, renderers = [], []
        for s in range(2):
            # the two pads touch opposite sides of the handle: their own stretch of its texture
            roll = self.grasp.roll + np.pi * s
            contacts.append(LineContact(self.grid, s == 1, self.grasp.butt, self.grasp.axis,
                                        self.grasp.s_k, profile, roll, trial_rng(seed, spec, 20 + s),
                                        drag_sigma_mm=sim["render"]["shear_spread_mm"]))
            look = looks[s] if self.noise else DigitLook(**{**looks[s].__dict__, "noise_std": 0.0})
            renderers.append(Renderer(look, self.grid, sim["render"], trial_rng(seed, spec, 30 + s)))
        self._contacts, self._renderers = contacts, renderers

    @property
    def contacts(self) -> list[LineContact]:
        if self._contacts is None:
            self._build_renderers()
        return self._contacts

    @property
    def renderers(self) -> list[Renderer]:
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
        return trial_rng(self.params["seed"], self.spec, 1000 + 100000 * sensor + index)

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
        rng = trial_rng(self.params["seed"], self.spec, 40)
        start_host_ns = self.t0_ns - int(round(nano["preroll_s"] * 1e9))
        offset_s = uniform(rng, nano["clock_offset_s"])
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
        arrival = self._arrival_ns(host_ns, lines[1:], quiet)
        return {"lines": lines, "arduino_ms": stamp_ms, "counts": counts, "start_host_ns": start_host_ns,
                "arrival_host_ns": arrival,
                "offset_s": offset_s, "rate_ppm": ppm, "sample_host_ns": np.rint(host_ns).astype(np.int64),
                "stamp_host_ns": np.rint(start_host_ns + offset_s * 1e9
                                         + stamp_ms * 1e6 / (1 + ppm * 1e-6)).astype(np.int64),
                "wrench": wrench, "clipped": int(((counts == 0) | (counts == layout.ADC_COUNTS)).sum())}

    def _arrival_ns(self, sample_host_ns: np.ndarray, lines: list[str], quiet: bool) -> np.ndarray:
        """When each line reaches the host (the recorder's force_arrival.csv): sent once the
        gauges are read, at the baud rate, then the USB adaptor's polling, the kernel and the
        reader thread; now and then the reader is not scheduled for tens of ms."""
        usb = self.sim["nano17"]["usb"]
        rng = trial_rng(self.params["seed"], self.spec, 41)      # its own stream: the log's draws stay as they were
        n = len(lines)
        send_ns = np.array([(len(ln) + 1) * 10 / usb["baud"] * 1e9 for ln in lines])
        poll = rng.uniform(0, usb["poll_ms"], n) * 1e6
        tail = rng.exponential(usb["delay_ms"], n) * 1e6
        hiccup = (rng.random(n) < usb["hiccup_rate"]) * rng.uniform(*usb["hiccup_ms"], n) * 1e6
        late = 0.0 if quiet else poll + tail + hiccup
        arrival = np.rint(sample_host_ns + send_ns + late).astype(np.int64)
        return np.maximum.accumulate(arrival)           # one reader thread: lines arrive in order

    def arrival_csv(self, ser: dict) -> str:
        rows = ["line,host_ns"] + [f"{i + 2},{t}" for i, t in enumerate(ser["arrival_host_ns"])]
        return "\n".join(rows) + "\n"

    def meta(self) -> layout.TrialMeta:
        return layout.TrialMeta(trial=self.spec.name, tool=self.spec.tool, kind=self.spec.kind,
                                orientation_deg=self.spec.orientation_deg, insertion_mm=self.spec.insertion_mm,
                                camera_fps=float(self.sim["camera"]["fps"]),
                                serial_hz=float(self.sim["nano17"]["serial_hz"]),
                                notes={"source": "simulated"})


def simulate_trial(spec: TrialSpec, params: dict, quiet: bool = False) -> dict:
    """Simulate one trial in memory (for tests): frames, stamps, truth and the Arduino log.

    quiet=True switches off camera noise, flicker, drift, ADC noise, sampling jitter and bias
    drift (the physics stays), so exact checks are possible.
    """
    trial = Trial(spec, params, noise=not quiet)
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


def _write_png(path: Path, img: np.ndarray) -> None:
    ok, buf = cv2.imencode(".png", img)
    if not ok:
        raise RuntimeError(f"PNG encoding failed for {path}")
    with atomic_path(path) as tmp:
        tmp.write_bytes(buf.tobytes())


def write_trial(session_dir: str | Path, spec: TrialSpec, params: dict) -> None:
    """Write one trial folder in the rig's layout (layout.py), every file atomically."""
    trial = Trial(spec, params)
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
    ser = trial.serial()
    write_text(tdir / "force.log", "\n".join(ser["lines"]) + "\n")
    write_text(tdir / ARRIVAL_NAME, trial.arrival_csv(ser))
    trial.meta().write(tdir)
