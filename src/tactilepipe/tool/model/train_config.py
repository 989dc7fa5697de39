"""One training run's settings (``TrainConfig``): what ``train`` runs with, and what a checkpoint
records and compares before it lets a run resume."""

from __future__ import annotations

from dataclasses import dataclass

from tactilepipe.core.errors import ArgumentError
from tactilepipe.tool.model.variants import NAMED_ARCHITECTURES


@dataclass
class TrainConfig:
    """One run's training settings. Every value comes from params.yaml ``tool_train`` (``from_params``)
    or from the run itself (variant, size, label scaling, seed): none has a default here but the
    variant's architecture, which a name of variants.NAMED_ARCHITECTURES implies."""
    variant: str                        # the variant's name (params.yaml tool_variants)
    depth: int                          # ResNet depth: 18, 34, 50, 101
    image_size: int                     # S of the (b, 4, S, S) inputs (must match the dataset)
    lr: float                           # Adam
    lr_schedule: str                    # constant (the paper) | cosine: per batch from lr down to 0 at max_epochs
    batch_size: int
    max_epochs: int
    patience: int | None                # epochs without a lower validation loss before stopping (None/0: never)
    normalise: str                      # minmax (normal force) | zscore (shear force)
    seed: int                           # model init, dropout and the per-epoch shuffle
    device: str                         # auto (CUDA when available, else CPU) | cpu | cuda | cuda:N
    amp: bool                           # mixed precision, on CUDA only (ignored on CPU)
    num_threads: int | None             # torch CPU threads while training (None: leave as is)
    max_train_batches_per_epoch: int | None   # cap for smoke runs (None: every batch)
    bn_recalibration_batches: int       # training batches that re-estimate BatchNorm statistics before
                                        # each validation (0: keep the running averages)
    gam_channel_gate: str               # sigmoid (ours) | none (the public code's GAM channel branch)
    width: int                          # channels of the first encoder stage (the paper: 64); all scale with it
    kernels: str                        # portable | native: numerical kernels (tool/model/kernels.py)
    channels_last: bool = True          # NHWC memory format (faster on CPU); not a parameter
    architecture: dict | None = None    # the variant's {"sensors": [[start, stop], ...], "gam": bool}
                                        # (variants.Architecture.as_dict); None: its name's, as first defined

    def __post_init__(self):
        if self.architecture is None:
            if self.variant not in NAMED_ARCHITECTURES:
                raise ArgumentError(f"model variant '{self.variant}': no architecture given (its sensors and gam)")
            self.architecture = NAMED_ARCHITECTURES[self.variant].as_dict()

    @classmethod
    def from_params(cls, tool_train: dict, *, variant: str, depth: int, image_size: int, normalise: str,
                    seed: int, architecture: dict | None = None) -> "TrainConfig":
        """The settings of one run from the ``tool_train`` parameter group and the run's own values."""
        t = tool_train
        return cls(variant=variant, architecture=architecture, depth=depth, image_size=image_size, normalise=normalise, seed=seed,
                   lr=t["lr"], lr_schedule=t["lr_schedule"], batch_size=t["batch_size"], max_epochs=t["max_epochs"],
                   patience=t["patience"], device=t["device"], amp=t["amp"], num_threads=t["num_threads"],
                   max_train_batches_per_epoch=t["max_train_batches_per_epoch"] or None,
                   bn_recalibration_batches=t["bn_recalibration_batches"], gam_channel_gate=t["gam_channel_gate"],
                   width=t["width"], kernels=t["kernels"])
