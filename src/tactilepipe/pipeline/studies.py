"""Every study's parameter checks in one place: the full validation of a params.yaml.

Each study keeps the checks of its own keys beside its code (volume/checks.py, tool/checks.py,
and papillarray/checks.py, the sensor's axis map, which the volume and drift stages share), so
that editing one re-runs that study's stages only. A stage run by hand runs its own study's
(the ``checks=`` of its ``@command``); the callers that stand for the whole file run all of them
through this module: the Snakemake workflow (workflow/rules/common.smk, before any job is
planned; the dvc.yaml generator plans through it), ``tactilepipe diff``, and tests and scripts
that mean "params.yaml as the workflow would take it". No pipeline stage's code holds this
module (only the commands that check the whole file: `diff`, `sessions`), so no stage's code
holds another study's checks. (Every process of the command line imports each study's command
module to build its parser, checks included, but runs only its own stage's.)
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tactilepipe.core import config
from tactilepipe.papillarray import checks as papillarray_checks
from tactilepipe.tool import checks as tool_checks
from tactilepipe.volume import checks as volume_checks

# the order a file with several mistakes is reported in: volume, the sensor, tool
CHECKS = (volume_checks.check, papillarray_checks.check, tool_checks.check)


def resolve(raw: dict, source: str = "params.yaml", overrides: dict | None = None) -> dict[str, Any]:
    """`tactilepipe.core.config.resolve` with every study's checks."""
    return config.resolve(raw, source, overrides, CHECKS)


def load_params(path: str | Path = config.DEFAULT_PARAMS, overrides: dict | None = None) -> dict[str, Any]:
    """`tactilepipe.core.config.load_params` with every study's checks."""
    return config.load_params(path, overrides, CHECKS)
