# tactilepipe: raw tactile recordings -> shards -> models -> metrics, tables, figures.
# Run:  snakemake --cores 2          (scenes and scale from params.yaml)
#       snakemake --cores 2 --config scale=smoke scenes='[volume]'

# Snakemake loads params.yaml at `configfile:` with no bound on its aliases: a file whose nested
# anchors stand for far more than it holds is refused first, in one line, before it fills the memory.
import sys
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
include: "workflow/rules/volume.smk"
include: "workflow/rules/drift.smk"
include: "workflow/rules/tool.smk"
include: "workflow/rules/regimes.smk"
include: "workflow/rules/study000.smk"
include: "workflow/rules/stages.smk"


rule all:
    input:
        scene_targets(P["scenes"]),
    default_target: True
