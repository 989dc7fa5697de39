"""The tool scenes: ``tool_normal`` / ``tool_shear`` learn the ``normal`` / ``shear`` force from that
kind of trial. Light on purpose (no numpy or pandas): the command-line parser imports it."""

from __future__ import annotations

from tactilepipe.core.errors import TactilepipeError

# scene -> the force label it learns (also the kind of trial it is built from) and how the labels
# are scaled for training (min-max for the normal force, z-score for shear, as study 000 does)
TOOL_SCENES = {"tool_normal": "normal", "tool_shear": "shear"}
LABEL_NORMALISATION = {"normal": "minmax", "shear": "zscore"}


def scene_label(scene: str) -> str:
    """The force label (and trial kind) of a tool scene: "normal" or "shear"."""
    if scene not in TOOL_SCENES:
        raise TactilepipeError(f"unknown tool scene '{scene}' (one of {', '.join(TOOL_SCENES)})")
    return TOOL_SCENES[scene]
