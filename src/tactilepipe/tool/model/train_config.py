"""One training run's configuration (``TrainConfig``): what ``train`` runs with, and what a checkpoint
records and compares before it lets a run resume.

It is the typed parameter slice every run reads (core/parameters/tool.py ``TrainingSettings``:
params.yaml ``tool_train`` but the keys that lay out the runs) plus the run's own values, so a new
training setting is a field there and a value in params.yaml, and reaches ``train`` as
``cfg.<name>`` with no edit here."""

from __future__ import annotations

from pydantic import model_validator

from tactilepipe.core.errors import ArgumentError
from tactilepipe.core.parameters.training import TrainingSettings
from tactilepipe.tool.model.variants import NAMED_ARCHITECTURES


class TrainConfig(TrainingSettings):
    """One run's training: every ``TrainingSettings`` field (from params.yaml ``tool_train``,
    ``from_params``) and the run's own values below. None has a default but the variant's
    architecture, which a name of variants.NAMED_ARCHITECTURES implies, and the memory format."""
    variant: str                        # the variant's name (params.yaml tool_variants)
    depth: int                          # ResNet depth: 18, 34, 50, 101
    image_size: int                     # S of the (b, 4, S, S) inputs (must match the dataset)
    normalise: str                      # minmax (normal force) | zscore (shear force)
    seed: int                           # model init, dropout and the per-epoch shuffle
    channels_last: bool = True          # NHWC memory format (faster on CPU); not a parameter
    architecture: dict | None = None    # the variant's {"sensors": [[start, stop], ...], "gam": bool}
                                        # (variants.Architecture.as_dict); None: its name's, as first defined

    @model_validator(mode="after")
    def _named_architecture(self) -> "TrainConfig":
        if self.architecture is None:
            if self.variant not in NAMED_ARCHITECTURES:
                raise ArgumentError(f"model variant '{self.variant}': no architecture given (its sensors and gam)")
            self.architecture = NAMED_ARCHITECTURES[self.variant].as_dict()
        return self

    @classmethod
    def from_params(cls, tool_train: dict, *, variant: str, depth: int, image_size: int, normalise: str,
                    seed: int, architecture: dict | None = None) -> "TrainConfig":
        """The settings of one run from the ``tool_train`` parameter group and the run's own values."""
        settings = {name: tool_train[name] for name in TrainingSettings.model_fields}
        return cls(**settings, variant=variant, architecture=architecture, depth=depth, image_size=image_size,
                   normalise=normalise, seed=seed)
