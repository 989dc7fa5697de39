"""The model variants of study 000's ablation (the one place a variant is defined), and the depths
of its ResNet regressor.

Each entry says which input channels each encoder reads (slices of the loader's four channels
[left, left_ref, right, right_ref]), whether the GAM blocks exist, the baseline that has the same
information (the like-for-like comparison of the model report), and how figures name and colour
it. The network builds a variant from this entry; the command line offers these names; the
workflow trains every variant when ``tool_train.variants`` is ``all``. Adding an entry here is all
a new variant needs. Kept free of torch, so the report and the command line read it cheaply.
"""

from __future__ import annotations

from dataclasses import dataclass

from tactilepipe.core.errors import ConfigError

BASELINES = ("mean_predictor", "tactile_rmse_linear", "rest_frame_rmse_linear", "one_finger_rmse_linear")


@dataclass(frozen=True)
class Variant:
    sensors: tuple[tuple[int, int], ...]   # per encoder: [start, stop) slice of the 4 input channels
    gam: bool                              # GAM blocks present (else identity)
    baseline: str                          # the baseline with the same information (one of BASELINES)
    label: str                             # its name in figures and tables
    colour: str                            # its colour in figures
    doc: str


VARIANTS: dict[str, Variant] = {
    "full": Variant(((0, 2), (2, 4)), True, "tactile_rmse_linear", "full model", "#C44E52",
                    "the published model: both fingers, each with its zero-force reference, GAMs on"),
    "no_ref": Variant(((0, 1), (2, 3)), True, "rest_frame_rmse_linear", "no reference frame", "#64B5CD",
                      "reference frames removed: each finger's encoder reads only its current frame (1 ch)"),
    "single": Variant(((0, 2),), True, "one_finger_rmse_linear", "single sensor", "#1f3d7a",
                      "left finger only (current + reference): one encoder + GAM(256), no fusion GAM; "
                      "the ResNet's first conv takes 256 channels"),
    "no_gam": Variant(((0, 2), (2, 4)), False, "tactile_rmse_linear", "no attention (GAM)", "#8172B2",
                      "both fingers with references, every GAM replaced by identity"),
}

# the ResNet regressor's depths: block kind and blocks per stage
DEPTHS: dict[int, tuple[str, list[int]]] = {
    18: ("basic", [2, 2, 2, 2]),
    34: ("basic", [3, 4, 6, 3]),
    50: ("bottleneck", [3, 4, 6, 3]),
    101: ("bottleneck", [3, 4, 23, 3]),
}

ALL = "all"


def chosen_variants(setting: str | list[str]) -> list[str]:
    """The variants ``tool_train.variants`` asks for: every variant (``all``, in VARIANTS order) or
    the ones listed, each of which must be defined."""
    if setting == ALL:
        return list(VARIANTS)
    unknown = [v for v in setting if v not in VARIANTS]
    if unknown:
        raise ConfigError(f"tool_train.variants: unknown variant(s) {unknown} (defined: {', '.join(VARIANTS)}; "
                          f"or '{ALL}')")
    return list(setting)


def _check() -> None:
    for name, v in VARIANTS.items():
        if v.baseline not in BASELINES:
            raise ConfigError(f"variant '{name}': baseline '{v.baseline}' is not one of {BASELINES}")


_check()
