"""Parameter groups of study 000's data and models: ingest, sync, splits, training, prediction,
and the study's own published data."""

from typing import Annotated, Literal

from pydantic import Field, NonNegativeFloat, PositiveFloat

from tactilepipe.core.parameters.base import Group, Pair, RequiredKeys, Triple, UniqueList
from tactilepipe.core.parameters.training import Kernels, TrainingSettings
from tactilepipe.core.tool_vocabulary import BASELINES, RESNET_DEPTHS

Depth = Literal[tuple(RESNET_DEPTHS)]      # the depths the network builds (core/tool_vocabulary.py)
Baseline = Literal[BASELINES]              # the baselines the model report fits (the same)
# A variant's name is the first part of its run names (tool/runs.py), which are [a-z_0-9]+; that no
# name reads as another run ("<name>_r<k>", "full_<...>") is checked with the other groups (config.py).
VariantName = Annotated[str, Field(pattern=r"^[a-z][a-z0-9]*(_[a-z0-9]+)*$")]


class ClockSync(Group):
    """Native trials: the Arduino clock refined against the images (tool/data/clock_sync.py)."""

    min_score: float = Field(ge=-1, le=1)
    max_finger_disagreement_s: PositiveFloat
    on_low_score: Literal["refuse", "host_clock", "drop"]
    min_force_range_n: PositiveFloat


class IngestWitness(Group):
    """Per native trial, the witnesses of its force labels (tool/data/witness.py): a trial one of
    them fails is left out of the dataset, named with its numbers."""

    adc_mid_counts: float = Field(gt=0, le=512, description="counts the unloaded gauges may sit from the ADC's "
                                                             "mid level 511.5")
    rate_rel: float = Field(gt=0, le=1, description="relative difference allowed between a declared rate "
                                                    "(meta.json) and the one the stamps show")
    rest_frames: int = Field(ge=1, le=1000, description="frames at each end of a trial where it rests")
    rest_n: float = Field(gt=0, le=100, description="N: |F| allowed at rest, at each end of a trial")
    rest_change_frac: float = Field(ge=0, le=1, description="the images show a finger at rest where its change "
                                                            "from the reference is within this fraction of its "
                                                            "5-95 % range over the trial (zero drift)")
    loaded_n: float = Field(gt=0, le=100, description="N: |F| from which a label counts as loaded (direction)")
    min_normal_share: float = Field(ge=0, le=1, description="median share of |F| that Fz carries while loaded")
    min_image_score: float = Field(ge=-1, le=1, description="correlation of tactile change and |F| at the labels' "
                                                            "clock (refined or arrival-stamped clocks only)")
    max_brightness_step_dn: float = Field(gt=0, le=255, description="gray levels a frame's mean brightness may "
                                                                    "change from one frame to the next")
    min_image_snr: float = Field(ge=0, le=1000, description="the images judge the labels where their change over "
                                                            "the trial is this many times its frame-to-frame noise")


class SessionWitness(Group):
    """The dataset's comparison of each trial with its session (tool/data/witness.py)."""

    max_z: float = Field(gt=0, le=1000, description="robust z beyond which a trial stands out")
    min_trials: int = Field(ge=2, le=100000, description="other trials a comparison needs (in the session, or in the "
                                                         "pose for the gain)")
    gain_floor: float = Field(gt=0, le=10, description="floor of the spread of log gain (force per unit change)")
    offset_floor_n: float = Field(gt=0, le=100, description="N: floor of the spread of Fz at rest (both ends)")
    lag_floor_s: float = Field(gt=0, le=10, description="s: floor of the spread of the fingers' lag difference")
    rate_floor: float = Field(gt=0, le=1, description="floor of the spread of log frame rate")
    max_lag_error_s: float = Field(gt=0, le=10, description="s: an arrival-stamped trial's image lag may lie this "
                                                          "far from its session's camera latency")


class RosTopics(Group):
    """Topics of trials recorded as ROS bags."""

    digit_left: str
    digit_right: str
    wrench: str


class ToolIngest(Group):
    """Where a recorded frame becomes a stored one."""

    stored_size: int = Field(ge=8, le=1024, description="side S of the square grayscale frames the shards and data "
                                                        "sets hold (the model's input is downscaled from them)")
    max_offset_s: PositiveFloat
    ros_topics: RosTopics
    clock: ClockSync
    witness: IngestWitness


class ToolSync(Group):
    """Pairing frames with force samples."""

    max_gap_s: PositiveFloat
    pair_rate_hz: NonNegativeFloat
    reference: Literal["first", "median_pre_contact"]
    contact_n: PositiveFloat
    normal_sign: Literal[-1, 1]
    witness: SessionWitness


class ToolSplit(Group):
    """Train/validation/test splits of the tool datasets."""

    fractions: Triple[Annotated[float, Field(gt=0, lt=1)]]
    repeats: int = Field(ge=1, le=100, description="how many draws of the default split every variant is trained "
                                                   "on (repeat 0 is the one the figures draw). At most 100: each "
                                                   "repeat trains every variant again (8 fill the default scale's "
                                                   "hour), and the workflow plans a job per run")
    holdout_pose: int = Field(ge=0, le=100, description="leave-one-pose-out: the n-th pose of every tool (at most "
                                                        "100: more poses than any grasp protocol records)")
    level_n: PositiveFloat


class SweepRun(Group):
    """An extra full-model run for error against run time."""

    depth: Depth
    image_size: int = Field(ge=8, le=1024, description="at most 1024, the largest tool_ingest.stored_size")


class ToolVariant(Group):
    """A model variant of study 000's ablation: what the network builds (sensors, gam) and how the
    model report compares and draws it (baseline, label, colour)."""

    sensors: list[Pair[Annotated[int, Field(ge=0, le=4)]]] = Field(
        min_length=1, max_length=4, description="per encoder, the [start, stop) slice of the loader's four input "
                                                "channels [left, left_ref, right, right_ref] it reads")
    gam: bool = Field(description="GAM blocks present (false: each is the identity)")
    baseline: Baseline = Field(description="the baseline with the same information (the like-for-like "
                                           "comparison of the model report)")
    label: str = Field(min_length=1, max_length=60, description="its name in figures and tables")
    colour: str = Field(pattern=r"^#[0-9A-Fa-f]{6}$", description="its colour in figures (#RRGGBB)")
    doc: str = Field(description="what it is, in a sentence")


class ToolTrain(TrainingSettings):
    """The CNN + GAM + ResNet model of study 000 and its ablations: the runs (which variants, split,
    depth and input size; the workflow reads these to lay out the training jobs, each run through
    its own definition) and the settings every run trains with."""

    variants: Literal["all"] | UniqueList[str] = Field(
        min_length=1, description="the model variants to train: all (every one tool_variants defines, in its "
                                  "order) or a list of their names")
    split: Literal["frame", "trial", "lopo"]
    loto: bool
    depth: Depth
    image_size: int = Field(ge=8, le=1024, description="side S of the square inputs the model is trained on "
                                                       "(the dataset's frames are area-downscaled to it; at most "
                                                       "1024, the largest tool_ingest.stored_size)")
    sweep: list[SweepRun]


class ToolReport(Group):
    """How the model report judges the variants' orderings (tool/report/verdicts.py)."""

    equivalence_margin: float = Field(
        gt=0, le=0.1, description="two variants whose MAE differs by less than this fraction of the full model's "
                                  "mean MAE are equivalent (when the whole 95 % interval of the difference lies "
                                  "inside it). At most 0.1: a wider margin would call differences that matter "
                                  "no difference")


class Predict(Group):
    """`tactilepipe predict`: one frame pair at a time, on a CPU other jobs share."""

    num_threads: int = Field(ge=1, le=1024, description="at most 1024, more cores than one machine has")
    wait_policy: Literal["passive", "active"]
    kernels: Kernels


class PublicFile(Group):
    """A Git LFS file of study 000's public repository, checked against its size and sha256."""

    url: str = Field(min_length=1)
    size: int = Field(ge=1, le=2**40, description="bytes (at most 1 TiB)")
    sha256: str = Field(pattern=r"^[0-9a-f]{64}$")


class PaperScores(Group):
    """The paper's full model on normal force (its frame-level test set)."""

    mae_n: NonNegativeFloat
    r2: float = Field(le=1)


PublicFileName = Annotated[str, Field(pattern=r"^[A-Za-z0-9_]+$")]


class PublicData(Group):
    """study 000's own recordings and published weights (docs/reproduce_study_000.md): read only by the
    opt-in pipeline in studies/000/"""

    session: str = Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_-]*$")
    files: Annotated[dict[PublicFileName, PublicFile],
                     RequiredKeys("data_normal", "data_shear", "best_model_normal", "best_model_shear")]
    paper: PaperScores
