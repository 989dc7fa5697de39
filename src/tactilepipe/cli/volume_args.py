"""What the volume study's commands share: the cross-key checks a stage runs on params.yaml by hand
(the study's own and its sensor's; the workflow runs every study's: tactilepipe/studies.py) and the
data set and folds the model stages read."""

from __future__ import annotations

from tactilepipe.cli.registry import arg
from tactilepipe.papillarray import checks as papillarray_checks
from tactilepipe.volume import checks as volume_checks

VOLUME_CHECKS = (volume_checks.check, papillarray_checks.check)

FOLDED = (arg("--dataset", required=True), arg("--folds", required=True))
