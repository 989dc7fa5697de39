# Rules generated from the stages that declare theirs (`rule=` of @command; pipeline/stage_rules.py):
# fixed input and output files under the build's folder, each passed as the stage's --<key>.


try:
    _STAGES = stage_rules.stage_rules()
except TactilepipeError as exc:
    raise WorkflowError(str(exc)) from None


for _stage in _STAGES:
    rule:
        name: _stage.name
        input:
            **_stage.named_inputs(RESULTS),
            code=stage_code(_stage.stage),
            params=param_stamp(_stage.stage),
        output:
            **_stage.named_outputs(RESULTS),
        localrule: _stage.local
        resources:
            **rule_resources(_stage.name),
        log:
            f"{LOGS}/{_stage.scene}/{_stage.name}.log",
        params:
            # a shell line is formatted when its job runs, when the loop's variable is long gone:
            # what it needs of this stage is captured here, as values (no machine's paths: a
            # changed value re-runs the job)
            stage=_stage.stage,
            files=_stage.file_args(RESULTS),
        shell:
            "{CLI} {params.stage} --stamp {input.params:q} {params.files} 2> {log:q}"


# A target per scene (`snakemake --cores 2 volume`): every file the scene ends in.
for _scene in scenes.SCENES:
    rule:
        name: _scene
        localrule: True
        input:
            scene_targets([_scene]),
