"""`simulate_tool`: the simulated DIGIT tool-force rig of study 000 (tool/sim/)."""

from typing import Literal

from pydantic import Field, NonNegativeFloat, PositiveFloat

from tactilepipe.core.parameters.base import Group, Pair, Triple, UniqueList


class ToolSpec(Group):
    """A rigid tool; its handle is what the two gels touch."""

    mass_g: float
    length_mm: float
    cg_from_butt_mm: float
    handle_radius_mm: float
    flat_width_mm: float
    half_thickness_mm: float
    end_radius_mm: float
    tip_offset_mm: float
    texture: Literal["none", "flutes", "knurl", "ribs", "grain"]
    texture_period_mm: float
    texture_depth_mm: float


class GraspPose(Group):
    """A grasp pose, set by hand."""

    orientation_deg: float
    insertion_mm: float
    lean_deg: float
    lateral_mm: float


class ToolGrasp(Group):
    """Re-grasping jitter and the contact mechanics of the two gel pads."""

    orientation_jitter_deg: float
    insertion_jitter_mm: float
    lean_jitter_deg: float
    lateral_jitter_mm: float
    grip_force_n: float
    grip_force_rel_std: float
    e_star_mpa: float
    e_star_sensor_rel_std: float
    shear_stiffness_n_per_mm2: float
    torsion_stiffness_nmm_per_rad: float
    pad_friction: float
    tip_pin_fraction: Pair[float]
    line_samples: float


class Press(Group):
    """Normal trials: pressing cycles with rests at 0 N."""

    rest_start_s: Pair[float]
    rise_s: Pair[float]
    hold_s: Pair[float]
    fall_s: Pair[float]
    rest_s: Pair[float]
    peak_force_n: Pair[float]
    peak_beta: Pair[float]
    tremor_rel: float


class Slide(Group):
    """Shear trials: the tip slides on the sensor under a normal load."""

    normal_load_n: Pair[float]
    load_ripple_rel: float
    ramp_s: float
    tip_friction: Pair[float]
    stroke_mm: Pair[float]
    stroke_axis_deg: float
    stroke_spread_deg: NonNegativeFloat
    stroke_s: Pair[float]
    pause_s: Pair[float]
    slide_v0_mm_s: float


class SerialUsb(Group):
    """How the Arduino's lines reach the host (the recorder stamps each on arrival)."""

    baud: PositiveFloat
    poll_ms: NonNegativeFloat
    delay_ms: NonNegativeFloat
    hiccup_rate: float = Field(ge=0, le=1)
    hiccup_ms: Pair[NonNegativeFloat]


class Nano17(Group):
    """The F/T sensor under the tip and its Arduino logger."""

    mount: Literal["upright", "inverted"]
    contact_offset_mm: float
    cap_height_mm: float
    serial_hz: float
    preroll_s: float
    postroll_s: float
    clock_offset_s: Pair[float]
    rate_error_ppm: float
    jitter_ms: float
    adc_noise_counts: float
    gauge_bias_counts: float
    gauge_bias_drift_counts: float
    usb: SerialUsb


class Nano17Calibration(Group):
    """The session's nano17.cal (6x6, N or N*mm per volt)."""

    full_scale_n: Triple[float]
    full_scale_nmm: Triple[float]
    full_scale_v: float
    gain_rel_std: float
    crosstalk_rel: float


class DigitCamera(Group):
    """The two DIGITs as digit-interface streams them."""

    fps: float
    fps_rel_error: float
    stamp_jitter_ms: float
    latency_s: Pair[float]


class DigitRender(Group):
    """Gel to image (digit_render.py)."""

    px_per_mm: float
    height_downsample: float
    h_max_mm: float
    soften_sigma_mm: float
    soften_iterations: float
    shear_spread_mm: float
    light_elevation_deg: float
    background: str | None
    background_shift_px: int = Field(ge=0, le=20)
    background_gain_jitter: float = Field(ge=0, le=0.3)
    background_jitter_dn: NonNegativeFloat
    shading_gain: NonNegativeFloat
    led_crosstalk: float = Field(ge=0, le=1)
    led_distance_px: float
    blemish_count: Pair[float]
    blemish_height_mm: float
    noise_std_dn: Pair[NonNegativeFloat]
    noise_channel_scale: Triple[NonNegativeFloat]
    led_gain_jitter: float
    drift_dn: float
    drift_period_s: Pair[float]
    warmup_dn: float
    warmup_tau_s: float


class PublicLayout(Group):
    """The public dataset layout written by simulate_public_session."""

    frame_stride: float


class SimulateTool(Group):
    """DIGIT tool-force rig (study 000)."""

    tools_used: UniqueList[str] = Field(min_length=1)
    tools: dict[str, ToolSpec] = Field(min_length=1)
    poses: list[GraspPose] = Field(min_length=1)
    poses_per_tool: int = Field(ge=1, le=100, description="at most 100 (poses lists the grasp poses to use)")
    normal_trials_per_pose: int = Field(ge=0, le=1000, description="at most 1000 per tool and pose: a simulated "
                                                                   "session's frames are all held in memory once")
    shear_trials_per_pose: int = Field(ge=0, le=1000, description="at most 1000, as normal_trials_per_pose")
    frames_per_trial: int = Field(ge=1, le=100000, description="at most 100000 (55 min at 30 fps)")
    shear_frames_per_trial: int = Field(ge=1, le=100000, description="at most 100000, as frames_per_trial")
    trial_spacing_s: float
    grasp: ToolGrasp
    press: Press
    slide: Slide
    nano17: Nano17
    calibration: Nano17Calibration
    camera: DigitCamera
    render: DigitRender
    public: PublicLayout
