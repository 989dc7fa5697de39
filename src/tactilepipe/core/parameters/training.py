"""The settings every training run of study 000 reads: the training stage's typed slice of
``tool_train``. A module of its own because it is code of that stage (tool/model/train_config.py
builds each run's configuration from it): an edit to another group's model re-runs no training."""

from typing import Literal

from pydantic import Field

from tactilepipe.core.parameters.base import Group

Kernels = Literal["portable", "native"]


class TrainingSettings(Group):
    """What every training run of the tool study reads: params.yaml ``tool_train`` but the keys that
    lay out the runs (tool.py ``ToolTrain`` adds those). A field added here and given a value in
    params.yaml reaches each run's stamp, its ``TrainConfig`` (tool/model/train_config.py) and the
    scene's provenance with no other edit, and re-runs the trainings only."""

    lr: float = Field(gt=0, le=10, description="Adam's learning rate (at most 10: far above any rate that trains; "
                                               "the paper's is 1e-3)")
    lr_schedule: Literal["constant", "cosine"] = Field(
        description="constant: Adam at lr throughout (the paper); cosine: per batch from lr down to 0 at max_epochs")
    batch_size: int = Field(ge=1, le=65536, description="frame pairs per batch (at most 65536: a batch of 64-px "
                                                       "pairs that size is 4 GB of input alone)")
    max_epochs: int = Field(ge=1, le=10000, description="at most 10000 (the default scale trains 8)")
    patience: int = Field(ge=1, le=10000, description="epochs without a better validation loss before stopping "
                                                     "(at most 10000, as max_epochs)")
    max_train_batches_per_epoch: int = Field(ge=0, le=10**7, description="0 = the whole training split every epoch; "
                                                                         "at most 1e7")
    bn_recalibration_batches: int = Field(
        ge=0, le=10000, description="training batches that re-estimate BatchNorm statistics before each validation "
                                    "(0: off; at most 10000)")
    device: Literal["auto", "cpu", "cuda"]
    amp: bool
    num_threads: int = Field(ge=1, le=1024, description="at most 1024, more cores than one machine has")
    gam_channel_gate: Literal["sigmoid", "none"] = Field(
        description="GAM channel branch: sigmoid-gated (ours) or ungated (the public code of study 000, "
                    "needed by its published weights)")
    width: int = Field(ge=1, le=512, description="channels of the first encoder stage (the paper: 64); every "
                                                 "layer's channels and the head scale with it. At most 512: the "
                                                 "weights grow with its square, 100 MB at 64 and 6.4 GB at 512")
    kernels: Kernels = Field(
        description="numerical kernels: portable (the same bytes on every x86 CPU with AVX2; one thread, "
                    "no oneDNN) or native (each library's fastest code for this CPU)")
