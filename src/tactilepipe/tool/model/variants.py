"""The model variants of study 000's ablation, as the code reads them (the ResNet depths and the
baselines they name: core/tool_vocabulary.py).

A variant is data: an entry of params.yaml ``tool_variants`` (validated by
core/parameters/tool.py ``ToolVariant``). Each says which input channels each encoder reads
(slices of the loader's four channels [left, left_ref, right, right_ref]), whether the GAM blocks
exist, the baseline that has the same information (the like-for-like comparison of the model
report), and how figures name and colour it. The network is built from its ``Architecture``
(sensors, gam), which a training run receives in its stamp and writes into its checkpoints, so a
checkpoint loads on its own. Kept free of torch, so the report and the workflow read it cheaply.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Architecture:
    """What the network builds a variant from."""
    sensors: tuple[tuple[int, int], ...]   # per encoder: [start, stop) slice of the 4 input channels
    gam: bool                              # GAM blocks present (else identity)

    def as_dict(self) -> dict:
        return {"sensors": [list(s) for s in self.sensors], "gam": self.gam}

    @classmethod
    def from_dict(cls, d: dict) -> "Architecture":
        return cls(tuple((int(a), int(b)) for a, b in d["sensors"]), bool(d["gam"]))


@dataclass(frozen=True)
class Variant:
    architecture: Architecture
    baseline: str                          # the baseline with the same information (one of BASELINES)
    label: str                             # its name in figures and tables
    colour: str                            # its colour in figures
    doc: str


def variant_of(entry: dict) -> Variant:
    """A ``tool_variants`` entry of the parameters as a Variant."""
    return Variant(Architecture.from_dict(entry), entry["baseline"], entry["label"], entry["colour"], entry["doc"])


def defined_variants(tool_variants: dict) -> dict[str, Variant]:
    """Every variant params.yaml ``tool_variants`` defines, in its order."""
    return {name: variant_of(entry) for name, entry in tool_variants.items()}


# What the four first variants were when a checkpoint recorded only a variant's name (before variants
# were parameters): such a checkpoint is built from its name's entry here. Also the architecture a
# name gives where no parameters are at hand (the public code's weights are the "full" model).
NAMED_ARCHITECTURES: dict[str, Architecture] = {
    "full": Architecture(((0, 2), (2, 4)), True),
    "no_ref": Architecture(((0, 1), (2, 3)), True),
    "single": Architecture(((0, 2),), True),
    "no_gam": Architecture(((0, 2), (2, 4)), False),
}
