# tactilepipe: raw tactile recordings -> shards -> models -> metrics, tables, figures.
# Run:  snakemake --cores 2          (scenes and scale from params.yaml)
#       snakemake --cores 2 --config scale=smoke scenes='[volume]'

import sys
from pathlib import Path

# One checkout, one code: the tactilepipe this workflow imports must be this checkout's src/. A venv
# shared by two checkouts, or a copy of the project run with the first one's venv, would otherwise
# run and track (as each rule's code inputs) the other tree's code. Checked here, before anything
# else of the package is used, and without calling it: the other tree's package may differ.
_OWN_PACKAGE = (Path(workflow.basedir) / "src" / "tactilepipe").resolve()
try:
    import tactilepipe
    _IMPORTED_PACKAGE = Path(tactilepipe.__file__).resolve().parent
except ImportError:
    sys.exit(f"error: Python cannot import tactilepipe (this workflow's code is {_OWN_PACKAGE}): "
             f"run it with this checkout's venv (make .venv/.installed)")
if _IMPORTED_PACKAGE != _OWN_PACKAGE:
    sys.exit(f"error: this workflow's code is {_OWN_PACKAGE}, but Python imports tactilepipe from {_IMPORTED_PACKAGE}: "
             f"run it with this checkout's venv (make .venv/.installed) or set PYTHONPATH={_OWN_PACKAGE.parent}")

# Snakemake loads params.yaml at `configfile:` with no bound on its aliases: a file whose nested
# anchors stand for far more than it holds is refused first, in one line, before it fills the memory.
from tactilepipe.core.errors import TactilepipeError
from tactilepipe.core.yamlsafe import check_yaml_file

try:
    check_yaml_file("params.yaml")
except TactilepipeError as exc:
    sys.exit(f"error: {exc}")

configfile: "params.yaml"


include: "workflow/rules/scheduler.smk"
include: "workflow/rules/common.smk"
include: "workflow/rules/dvc.smk"
include: "workflow/rules/simulate.smk"
include: "workflow/rules/ingest.smk"
include: "workflow/rules/stages.smk"
include: "workflow/rules/volume.smk"
include: "workflow/rules/drift.smk"
include: "workflow/rules/tool.smk"
include: "workflow/rules/regimes.smk"
include: "workflow/rules/study000.smk"


rule all:
    input:
        scene_targets(P["scenes"]),
    default_target: True
