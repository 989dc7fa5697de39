"""The scene argument the tool study's model and report stages share."""

from __future__ import annotations

from tactilepipe.cli.registry import arg
from tactilepipe.tool.scenes import TOOL_SCENES

SCENE = arg("--scene", choices=list(TOOL_SCENES), required=True)
