# Rules generated from the stages that declare theirs (`rule=` of @command; pipeline/stage_rules.py):
# fixed input and output files under the build's folder, each passed as the stage's --<key>.


try:
    _STAGES = stage_rules.stage_rules()
except TactilepipeError as exc:
    raise WorkflowError(str(exc)) from None


def declared_report_items(stage):
    """The outputs the stage names under ``report``, marked as items of `snakemake --report`; a
    caption file missing stops the workflow as it is read, naming it."""
    items = {}
    for key, (path, caption, kind, labels) in stage.report_items(RESULTS).items():
        if not (Path(workflow.basedir) / "workflow" / "rules" / caption).is_file():
            raise WorkflowError(f"stage {stage.stage}: its report item {path} needs its caption, "
                                f"workflow/{caption.removeprefix('../')} (which data, scale and split it shows)")
        items[key] = report(path, caption=caption, category=stage.scene, subcategory=kind, labels=labels)
    return items


for _stage in _STAGES:
    rule:
        name: _stage.name
        input:
            **_stage.named_inputs(RESULTS),
            code=stage_code(_stage.stage),
            params=param_stamp(_stage.stage),
        output:
            **_stage.named_outputs(RESULTS) | declared_report_items(_stage),
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
