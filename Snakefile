# tactilepipe: raw tactile recordings -> shards -> models -> metrics, tables, figures.
# Run:  snakemake --cores 2          (scenes and scale from params.yaml)
#       snakemake --cores 2 --config scale=smoke scenes='[volume]'

configfile: "params.yaml"


include: "workflow/rules/scheduler.smk"
include: "workflow/rules/common.smk"
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
