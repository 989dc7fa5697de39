"""Parameter groups of study 001: the PapillArray lift rig (volume scene) and the drift experiment."""

from typing import Annotated, Literal

from pydantic import Field, NonNegativeFloat, PositiveFloat

from tactilepipe.core.parameters.base import Group, Triple, UniqueList, overlay_of

SampleRate = Literal[100, 250, 500, 1000]       # the PapillArray driver's rates, Hz
RecordedAxis = Literal["+x", "-x", "+y", "-y", "+z", "-z"]


class AxisMap(Group):
    """The recorded axis (and sign) that reads each documented axis of one sensor."""

    x: RecordedAxis
    y: RecordedAxis
    z: RecordedAxis


class PapillarrayAxes(Group):
    """Per sensor: the recorded axis (and sign) that reads each documented axis."""

    sensor_0: AxisMap
    sensor_1: AxisMap


class GraspRegime(Group):
    """How the gripper sets the pads' normal force: the keys each of `volume_regimes.regimes` may set."""

    grip_regime: Literal["force", "position", "retighten"]
    crosstalk_t_to_n: float = Field(ge=0, le=1)


class PositionGrip(Group):
    """grip_regime position: pads and container wall are springs in series."""

    squeeze_mm: PositiveFloat
    squeeze_std_mm: NonNegativeFloat
    wall_modulus_mpa: PositiveFloat
    wall_thickness_mm: PositiveFloat
    container_radius_mm: PositiveFloat
    wall_contact_length_mm: PositiveFloat
    container_capped: bool
    container_capacity_ml: PositiveFloat
    dimple_area_mm2: PositiveFloat
    atmospheric_kpa: PositiveFloat


class RetightenGrip(Group):
    """grip_regime retighten: the grip rises while a loaded pillar slips."""

    rate_n_per_s: PositiveFloat
    latency_s: NonNegativeFloat
    max_grip_n: PositiveFloat


class SimulateVolume(GraspRegime):
    """Physics of the lift rig (study 001)."""

    volumes_ml: UniqueList[NonNegativeFloat] = Field(min_length=2)
    lifts_per_volume: int = Field(ge=1, le=10000, description="at most 10000 per volume")
    unseen_volumes_ml: UniqueList[NonNegativeFloat]
    unseen_lifts_per_volume: int = Field(ge=0, le=10000, description="at most 10000 per volume")
    rate_hz: SampleRate
    pose_rate_hz: PositiveFloat
    container_mass_g: PositiveFloat
    lift_height_m: PositiveFloat
    lift_duration_s: PositiveFloat
    hold_duration_s: PositiveFloat
    grip_force_n: PositiveFloat
    grip_force_rel_std: NonNegativeFloat
    pillar_normal_stiffness_n_per_mm: PositiveFloat
    pillar_tangential_stiffness_n_per_mm: PositiveFloat
    pillar_height_steps_mm: Triple[NonNegativeFloat]
    pillar_pitch_mm: PositiveFloat
    sensor_stiffness_mismatch: float = Field(ge=0, le=0.5)
    friction_static: PositiveFloat
    friction_kinetic: PositiveFloat
    grasp_tilt_std_deg: NonNegativeFloat
    contact_tilt_std_deg: NonNegativeFloat
    noise_std_n: NonNegativeFloat
    bias_residual_std_n: NonNegativeFloat
    drift_inf_n: float
    drift_per_kg_n: float
    drift_tau_s: PositiveFloat
    lift_cycle_s: PositiveFloat
    pillar_travel_mm: PositiveFloat
    creep_fractions: list[Annotated[float, Field(ge=0, lt=1)]] = Field(max_length=4)
    creep_tau_s: list[PositiveFloat] = Field(max_length=4)
    creep_integrator: Literal["exponential", "implicit_euler", "rk4", "euler"]
    creep_substeps: int = Field(ge=1, le=1000)
    position: PositionGrip
    retighten: RetightenGrip


class SimulateDrift(Group):
    """Study 001's drift experiment (section 3)."""

    duration_min: PositiveFloat
    every_min: PositiveFloat
    record_s: PositiveFloat
    load_g: NonNegativeFloat
    rate_hz: SampleRate


class Segment(Group):
    """How each lift's off-table phase is found."""

    method: Literal["auto", "pose", "force"]
    pose_lift_threshold_mm: PositiveFloat
    force_fraction: float = Field(gt=0, le=1)
    force_smooth_s: PositiveFloat
    min_off_table_s: PositiveFloat


class PapillarrayIngest(Group):
    """Checks of a PapillArray bag as it is ingested (the volume and drift studies)."""

    max_span_offset_s: PositiveFloat = Field(description="s the two sensors' first (and last) header stamps may "
                                                         "differ: the driver publishes both in one loop")


class VolumeChecks(Group):
    """Each lift's label and sensors against the other lifts of its session (volume/witness.py)."""

    min_session_lifts: int = Field(ge=3, le=10000, description="fewer lifts in a session: no session comparison or "
                                   "label fit, only the lower bound (the pads carry the labelled water); at most "
                                   "10000, as lifts_per_volume")
    outlier_k: PositiveFloat = Field(description="robust standard deviations (1.4826 x MAD over the session) "
                                                 "beyond which a lift stands out")
    rest_floor_n: PositiveFloat = Field(description="N: a sensor's rest level within this of the session's never "
                                                    "stands out")
    load_share_floor_n: PositiveFloat = Field(description="N: a pad's share of the carried load within this of "
                                                          "the session's never stands out")
    grip_share_floor: float = Field(gt=0, lt=0.5, description="a pad's share of the two pads' grip within this of "
                                                              "the session's never stands out")
    label_floor_n: PositiveFloat = Field(description="N: a lift's carried load within this of the session's fit "
                                                     "is never off it")
    label_slope_rel_tol: float = Field(gt=0, lt=1, description="the fit's slope must be 1 g of water per ml x g "
                                                               "within this fraction")


class Folds(Group):
    """Repeated seeded train/test draws stratified by volume."""

    n_folds: int = Field(ge=1, le=1000, description="at most 1000 draws (each trains every model again)")
    train_lifts_per_volume: int = Field(ge=1, le=10000, description="at most 10000, as lifts_per_volume")
    test_lifts_per_volume: int = Field(ge=1, le=10000, description="at most 10000, as lifts_per_volume")


class MlpGrid(Group):
    """Grid search on the first fold's training lifts (lift-grouped inner CV)."""

    hidden_units: list[Annotated[int, Field(ge=1, le=4096)]] = Field(min_length=1, description="each at most 4096")
    alpha: list[NonNegativeFloat] = Field(min_length=1)
    learning_rate: list[PositiveFloat] = Field(min_length=1)
    inner_folds: int = Field(ge=2, le=100, description="at most 100")
    modality: str


ModalityName = Annotated[str, Field(pattern=r"^[a-z0-9_]+$")]
ForceAxes = Annotated[UniqueList[Literal["fx", "fy", "fz"]], Field(min_length=1)]


class Mlp(Group):
    """Study 001's MLP (hyper-parameters from its grid search)."""

    modalities: dict[ModalityName, ForceAxes] = Field(min_length=1)
    hidden_units: int = Field(ge=1, le=4096, description="at most 4096 (the study's grid goes to 8)")
    alpha: NonNegativeFloat
    batch_size: int = Field(ge=1, le=10**6, description="at most 1e6 samples")
    learning_rate: PositiveFloat
    tol: NonNegativeFloat
    n_iter_no_change: int = Field(ge=1, le=10**6, description="at most 1e6, as max_iter")
    max_iter: int = Field(ge=1, le=10**6, description="at most 1e6 epochs")
    grid: MlpGrid
    restarts: int = Field(ge=1, le=1000, description="at most 1000 initialisations per fit")


class Baseline(Group):
    """The algebraic friction baseline: est_vol = 1000 (Fy + mu Fz) / G - m_cont."""

    mu_min: NonNegativeFloat
    mu_max: PositiveFloat
    n_mu: int = Field(ge=2, le=10**6, description="at most 1e6 grid points")
    gravity: PositiveFloat
    container_mass_g: NonNegativeFloat


class Drift(Group):
    """The drift analysis: model fits and the recalibration tolerance."""

    poly_degrees: list[Annotated[int, Field(ge=1, le=20)]] = Field(min_length=1, description="each at most 20 (a "
                                                                                                 "higher polynomial only fits noise)")
    tolerance_n: PositiveFloat


class OnTable(Group):
    """Fz windows with the gripper closed and the container on the table, before lift-off and after set-down."""

    guard_s: NonNegativeFloat
    window_s: PositiveFloat


RegimeName = Annotated[str, Field(pattern=r"^[a-z][a-z0-9_]*$")]


class VolumeRegimes(Group):
    """`make regimes`: Table 1 under each grasp regime (not part of `snakemake --cores 2`)."""

    regimes: dict[RegimeName, overlay_of(GraspRegime)] = Field(min_length=1)
    on_table: OnTable
