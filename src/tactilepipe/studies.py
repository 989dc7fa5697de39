"""The studies of this project, the one module that lists them: their contracts with the
workflow (``contracts()``: each package's contract.py, core/study.py) and their parameter checks
(``CHECKS``, the full validation of a params.yaml). The workflow's library (pipeline/) reads every
study through these, and imports no study package itself.

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

from functools import cache
from pathlib import Path
from types import ModuleType
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


@cache
def contracts() -> dict[str, ModuleType]:
    """Each study's contract (its contract.py, core/study.py) by study name, in the order the
    workflow reads their sessions and lists their scenes. Imported when first asked for: a stage's
    command line imports this module for the checks alone (cli/sessions.py names them), never the
    contracts, which are the workflow's code, not a stage's."""
    from tactilepipe.drift import contract as drift
    from tactilepipe.tool import contract as tool
    from tactilepipe.volume import contract as volume
    return {c.STUDY: c for c in (volume, drift, tool)}
