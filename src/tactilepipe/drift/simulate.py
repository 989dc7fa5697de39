"""Simulated drift experiment of study 001 (paper section 3), written as PapillArray bags.

One sensor lies flat, pillars up. The driver's bias request zeroes it at t = 0, then it heats for
``duration_min``; every ``every_min`` a ``record_s`` recording is taken. Run "unloaded": nothing
on it. Run "loaded": a ``load_g`` object is put on the sensor after ~0.5 s of each recording and
lifted off ~0.5 s before its end (0.3-s minimum-jerk ramps), as in the lab.

Measurement model - the same as the lift simulator's (`tactilepipe.volume.simulate`), with the
same numbers read from ``params["simulate_volume"]``, so both scenes describe one sensor:
- thermal drift of global Fz: dF(t) = (drift_inf_n + drift_per_kg_n * load_kg(t)) (1 - exp(-t/tau)),
  t = time since the bias request;
- residual bias left by the bias request (per pillar and axis, drawn once per run: one bias);
- white pillar noise (noise_std_n per pillar and axis);
- viscoelastic creep of the pillars under the weight and the pillars' measuring range
  (`tactilepipe.papillarray.viscoelastic`, `tactilepipe.papillarray.physics.saturate`);
- a tiny slow ambient wobble (room air-conditioning cycle), AMBIENT_WOBBLE_N.

What "load" means when the weight is only on during recordings: the exponential factor is the
sensor's own heating and runs with time since the bias whatever is on it. The two terms of
dF_inf are read as an offset (zero) drift, present always, and a span (gain) drift proportional
to the load carried *at that instant* - the transducer's sensitivity changes with temperature,
so the error it makes on a weight scales with that weight. We do not let the load "heat" the
sensor: a passive 500 g object carried for 5 s every 5 min dissipates no power. Hence the
loaded run's unloaded parts drift like the unloaded run (~0.3 N in 30 min) while its reading of
the weight drifts by ~0.5 N (the paper's two numbers). It is also exactly the lift simulator's
law with its instantaneous ``carried`` load. The span drift of each pillar is proportional to
that pillar's share of the load; the offset drift is spread evenly, as in the lift simulator.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tactilepipe.papillarray import messages as pa
from tactilepipe.papillarray.bagio import write_bag
from tactilepipe.drift import RUNS, parse_recording_name, recording_name
from tactilepipe.core.errors import ConfigError
from tactilepipe.papillarray import viscoelastic
from tactilepipe.papillarray.physics import (G, SESSION_EPOCH_S, minimum_jerk, normal_load_map,
                                            pillar_offsets_mm, saturate)

TOPIC = pa.sensor_topic(0, 0)
FRAME_ID = "hub_0/sensor_0"
DRIFT_STREAM = 3001          # keeps this scene's random streams apart from the lift simulator's
RUN_GAP_S = 7200             # the loaded run starts 2 h after the unloaded one (cooled, re-biased)
PLACE_AT_S = 0.5             # the object goes on this long after the recording starts ...
REMOVE_BEFORE_END_S = 0.8    # ... and starts coming off this long before it ends
RAMP_S = 0.3                 # placement / removal by hand: a short minimum-jerk ramp
AMBIENT_WOBBLE_N = 0.01      # amplitude of a slow room-temperature wobble of global Fz
AMBIENT_PERIOD_S = 660.0     # one air-conditioning cycle (~11 min)
CONTACT_THRESHOLD_N = 0.05   # a pillar reports in_contact above this true normal force


def recording_times_min(sd: dict) -> list[int]:
    """Minutes since the bias at which recordings start: 0, every_min, ..., duration_min."""
    times = np.arange(0.0, sd["duration_min"] + 1e-9, sd["every_min"])
    if not np.allclose(times, np.round(times)):
        raise ConfigError(f"simulate_drift: every_min={sd['every_min']} and duration_min="
                          f"{sd['duration_min']} must give whole minutes (bag names are <run>_t<MM>)")
    if sd["record_s"] < REMOVE_BEFORE_END_S + PLACE_AT_S + 2 * RAMP_S + 0.5:
        raise ConfigError(f"simulate_drift: record_s={sd['record_s']} is too short to place and "
                          "remove the weight with a loaded part to measure (need >= 2.4 s)")
    if sd["record_s"] > sd["every_min"] * 60:
        raise ConfigError("simulate_drift: record_s must not exceed every_min (recordings overlap)")
    return [int(round(t)) for t in times]


def session_plan(params: dict) -> list[str]:
    """Bag names (stems) of a simulated session, in recording order of each run.

    Without a weight (load_g = 0) the loaded run would repeat the unloaded one, so it is left out.
    """
    sd = params["simulate_drift"]
    runs = [r for r in RUNS if r != "loaded" or sd["load_g"] > 0]
    return [recording_name(run, t) for run in runs for t in recording_times_min(sd)]


def thermal_drift_n(t_since_bias_s, load_kg, sim: dict) -> np.ndarray:
    """Drift of global Fz (N): the lift simulator's law dF_inf(load) (1 - exp(-t / tau))."""
    heating = 1.0 - np.exp(-np.asarray(t_since_bias_s, float) / sim["drift_tau_s"])
    return (sim["drift_inf_n"] + sim["drift_per_kg_n"] * np.asarray(load_kg, float)) * heating


def load_profile_n(t: np.ndarray, record_s: float, load_n: float) -> np.ndarray:
    """True weight on the sensor during one loaded recording: put on, held, taken off."""
    on = minimum_jerk(t - PLACE_AT_S, RAMP_S, 1.0)[0]
    off = minimum_jerk(t - (record_s - REMOVE_BEFORE_END_S), RAMP_S, 1.0)[0]
    return load_n * (on - off)


def _run_constants(seed: int, run_index: int, sim: dict) -> dict:
    """What one bias request fixes for a whole run: residual bias and ambient phase."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, DRIFT_STREAM, run_index]))
    return {"bias_residual": sim["bias_residual_std_n"] * rng.standard_normal((9, 3)),
            "ambient_phase": rng.uniform(0, 2 * np.pi)}


def simulate_recording(name: str, params: dict) -> dict:
    """One recording: true load (T,), true thermal drift (T,) and measured pillar forces (T, 9, 3)."""
    run, t_min = parse_recording_name(name)
    sd, sim, seed = params["simulate_drift"], params["simulate_volume"], params["seed"]
    run_index = RUNS.index(run)
    const = _run_constants(seed, run_index, sim)
    rng = np.random.default_rng(np.random.SeedSequence([seed, DRIFT_STREAM, run_index, t_min]))

    rate = sd["rate_hz"]
    t = np.arange(int(round(sd["record_s"] * rate))) / rate
    load_n = sd["load_g"] / 1000.0 * G if run == "loaded" else 0.0
    total = load_profile_n(t, sd["record_s"], load_n)
    # The object rests on the 3x3 pillars of different heights (the lift rig's pillar model),
    # with a small random tilt each time it is put down.
    tilt = np.tan(np.deg2rad(sim["contact_tilt_std_deg"]) * rng.standard_normal(2))
    true = np.zeros((len(t), 9, 3))
    true[..., 2] = normal_load_map(total, pillar_offsets_mm(sim["pillar_height_steps_mm"]), tilt,
                                   sim["pillar_pitch_mm"], sim["pillar_normal_stiffness_n_per_mm"])

    t_since_bias = t_min * 60.0 + t
    heating = 1.0 - np.exp(-t_since_bias / sim["drift_tau_s"])
    offset_drift = sim["drift_inf_n"] * heating                                   # (T,)
    span_drift = sim["drift_per_kg_n"] / G * true[..., 2] * heating[:, None]      # (T, 9)
    ambient = AMBIENT_WOBBLE_N * np.sin(2 * np.pi * t_since_bias / AMBIENT_PERIOD_S + const["ambient_phase"])

    # the pillars creep under the weight (the lift simulator's viscoelastic model), then the errors
    measured = viscoelastic.integrate_params(true, 1.0 / rate, sim) + const["bias_residual"][None]
    measured[..., 2] += span_drift + ((offset_drift + ambient) / 9.0)[:, None]
    measured += sim["noise_std_n"] * rng.standard_normal(measured.shape)
    measured, saturated = saturate(measured, sim)
    stiffness = np.array([sim["pillar_tangential_stiffness_n_per_mm"]] * 2 + [sim["pillar_normal_stiffness_n_per_mm"]])
    return {"t": t, "run": run, "t_min": t_min, "load_n": total,
            "drift_n": thermal_drift_n(t_since_bias, total / G, sim),
            "force": measured.astype(np.float32), "disp": (measured / stiffness).astype(np.float32),
            "in_contact": true[..., 2] > CONTACT_THRESHOLD_N, "true_force": true,
            "saturated_samples": int(saturated.any(axis=(1, 2)).sum())}


def recording_start_ns(run: str, t_min: int) -> int:
    """Fixed clock (no wall time) so the same seed gives byte-identical bags."""
    return (SESSION_EPOCH_S + RUNS.index(run) * RUN_GAP_S + int(t_min) * 60) * 1_000_000_000


def write_drift_bag(path: str | Path, name: str, params: dict) -> dict:
    """Simulate recording ``name`` (e.g. "loaded_t05") and write it atomically as a ROS1 bag."""
    rec = simulate_recording(name, params)
    run_start = recording_start_ns(rec["run"], 0)
    stamps = recording_start_ns(rec["run"], rec["t_min"]) + np.round(rec["t"] * 1e9).astype(np.int64)
    tus = (stamps - run_start) // 1000         # the driver's microsecond clock since power-on
    raws = pa.encode_sensor_states(stamps, tus, rec["disp"], rec["force"], rec["in_contact"],
                                   np.zeros((len(stamps), 9), np.int32), frame_id=FRAME_ID)
    write_bag(path, {TOPIC: (pa.SENSOR_STATE, stamps.tolist(), raws)})
    return rec


def write_session_meta(out_dir: str | Path, params: dict) -> None:
    """The session's ``session.json``: what the rig knows about it (the weight it put on)."""
    from tactilepipe.core.atomic import write_json
    from tactilepipe.drift import SESSION_META
    write_json(Path(out_dir) / SESSION_META, {"reference_load_g": params["simulate_drift"]["load_g"]})
