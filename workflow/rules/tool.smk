# Study 000 data stages, shared by the tool_normal (Fz) and tool_shear (Fs) scenes:
# trials (native, public layout or ROS bags) -> one shard per trial -> per-target dataset
# (sync, references, decoded arrays) -> splits, QC report and data figures.

SPLIT_NAME = "(frame|public_frame|trial|lopo)(_r[1-9][0-9]*)?|loto_[A-Za-z0-9_-]+"   # tool/data/splits.py; public_frame: study000.smk


# By hand: writes a session under raw/, outside the build's folder, from its scale's stamp; made
#   in a loop, the simulators' rules changed their recorded commands (decision 0035)
rule tool_simulate:
    input:
        background=tool_background_frame(),
        code=stage_code("tool-simulate"),
        params=param_stamp("tool-simulate"),
    output:
        cal="raw/tool/{session}/nano17.cal",
        meta=[f"raw/tool/{{session}}/{name}/meta.json" for name in simulated_names("tool")],
    wildcard_constraints:
        session="sim-[A-Za-z0-9_-]+",
    params:
        out_dir=lambda w: f"raw/tool/{w.session}",
    threads: 2
    resources:
        **rule_resources("tool_simulate"),
    log:
        f"{LOGS}/tool_simulate/{{session}}.log",
    shell:
        "{CLI} tool-simulate --stamp {input.params:q} --out-dir {params.out_dir:q} --jobs {threads} 2> {log:q}"


# By hand: a job per recording of the session sheet ({session}/{trial}), whose format, path and
#   content stamp come from the sheet
rule tool_ingest:
    input:
        trial=ingest_inputs,
        content=content_stamp,
        code=stage_code("tool-ingest"),
        params=param_stamp("tool-ingest"),
    output:
        f"{RESULTS}/tool/shards/{{session}}/{{trial}}.parquet",
    params:
        fmt=lambda w: SHEET.recording("tool", w.session, w.trial).format,
        path=lambda w: SHEET.recording("tool", w.session, w.trial).path,
    resources:
        **rule_resources("tool_ingest"),
    log:
        f"{LOGS}/tool_ingest/{{session}}/{{trial}}.log",
    shell:
        "{CLI} tool-ingest --stamp {input.params:q} {params.path:q} --format {params.fmt} --out {output:q} > {log:q} 2>&1"


# By hand: a job per session, whose shards come from the session sheet
rule tool_clock_figure:
    input:
        shards=lambda w: shards("tool", w.session),
        code=stage_code("tool-clock-figure"),
        params=param_stamp("tool-clock-figure"),
    output:
        png=f"{RESULTS}/tool/qc/{{session}}_clock_sync.png",
        svg=f"{RESULTS}/tool/qc/{{session}}_clock_sync.svg",
    resources:
        **rule_resources("tool_clock_figure"),
    log:
        f"{LOGS}/tool_clock_figure/{{session}}.log",
    shell:
        "{CLI} tool-clock-figure --shards {input.shards:q} --out {output.png:q} > {log:q} 2>&1"


# By hand: a job per tool scene ({scene}), reading every shard the session sheet names
rule tool_dataset:
    input:
        # every trial, either kind: the pressing trials give the session's camera latency, which
        # times the sliding trials' labels too (tool/data/session_clock.py)
        shards=lambda w: shards("tool"),
        code=stage_code("tool-dataset"),
        params=param_stamp("tool-dataset"),
    output:
        frames=f"{RESULTS}/{{scene}}/data/frames.npy",
        references=f"{RESULTS}/{{scene}}/data/references.npy",
        samples=f"{RESULTS}/{{scene}}/data/samples.parquet",
        qc=f"{RESULTS}/{{scene}}/data/qc.json",
    wildcard_constraints:
        scene="tool_normal|tool_shear",
    params:
        kind=lambda w: scene_label(w.scene),
    resources:
        **rule_resources("tool_dataset"),
    log:
        f"{LOGS}/{{scene}}/dataset.log",
    shell:
        "{CLI} tool-dataset --stamp {input.params:q} --kind {params.kind} --shards {input.shards:q} "
        "--out-dir {RESULTS}/{wildcards.scene}/data 2> {log:q}"


# A split is a second's work on the sample table: on a cluster it runs where Snakemake runs
# instead of queueing as a job of its own (each scene has one per repeat and held-out tool).
localrules:
    tool_split,


# By hand: a job per split of a tool scene ({scene}/{split}), the split names drawn from
#   params.yaml
rule tool_split:
    input:
        samples=f"{RESULTS}/{{scene}}/data/samples.parquet",
        code=stage_code("tool-split"),
        params=param_stamp("tool-split"),
    output:
        f"{RESULTS}/{{scene}}/splits/{{split}}.json",
    wildcard_constraints:
        scene="tool_normal|tool_shear",
        split=SPLIT_NAME,
    params:
        label=lambda w: scene_label(w.scene),
    resources:
        **rule_resources("tool_split"),
    log:
        f"{LOGS}/{{scene}}/split_{{split}}.log",
    shell:
        "{CLI} tool-split --stamp {input.params:q} --data-dir {RESULTS}/{wildcards.scene}/data --split {wildcards.split} "
        "--label {params.label} --out {output:q} 2> {log:q}"


# By hand: a job per tool scene, reading the trials' raw files the session sheet names
rule tool_data_report:
    input:
        data=rules.tool_dataset.output,
        raw=lambda w: tool_contract.trial_inputs(SHEET, scene_label(w.scene)),   # the pressing strip shows their frames
        code=stage_code("tool-data-report"),
        params=param_stamp("tool-data-report"),
    output:
        qc=reported([f"{RESULTS}/{{scene}}/qc.md"], "{scene}", "tool")[0],
        figures=reported(tool_contract.figures(RESULTS + "/{scene}/figures", tool_contract.DATA_FIGURES), "{scene}", "tool"),
    wildcard_constraints:
        scene="tool_normal|tool_shear",
    resources:
        **rule_resources("tool_data_report"),
    log:
        f"{LOGS}/{{scene}}/data_report.log",
    shell:
        "{CLI} tool-data-report --stamp {input.params:q} --scene {wildcards.scene} --in-dir {RESULTS}/{wildcards.scene} 2> {log:q}"


# A target list, not a stage.
rule tool_data:
    # the data stages of both tool scenes, without models (DVC stage tool_data)
    localrule: True
    input:
        scene_targets(["tool_normal", "tool_shear"], data_only=True),


# --- models ------------------------------------------------------------------------------------
# Runs (tool/runs.py): each variant on every repeat of the default split, the full model leaving
# out each tool in turn, and the sweep (other depth / input size, for error against run time).


# By hand: a job per run of the run list ({scene}/{run}), each with its own stamp (run_stamp)
rule tool_train:
    # everything the job reads but its data and split is in its own stamp (run_stamp): the run's
    # variant, split name, depth and size, and the training settings
    input:
        data=rules.tool_dataset.output,
        split=lambda w: f"{RESULTS}/{w.scene}/splits/{run_spec(w.run)[1]}.json",
        code=stage_code("tool-train"),
        params=run_stamp,
    output:
        evaluation=f"{RESULTS}/{{scene}}/models/{{run}}/eval.json",
        predictions=f"{RESULTS}/{{scene}}/models/{{run}}/predictions.parquet",
        # best.pt, last.pt and history.csv are written beside them but not declared: Snakemake
        # deletes the declared outputs of a killed job, and last.pt must survive to resume it
    wildcard_constraints:
        scene="tool_normal|tool_shear",
        run="[a-z_0-9]+",
    threads: P["tool_train"]["num_threads"]
    resources:
        **rule_resources("tool_train"),
    log:
        f"{RESULTS}/logs/{{scene}}/train_{{run}}.log",
    shell:
        "{CLI} tool-train --stamp {input.params:q} --scene {wildcards.scene} --data-dir {RESULTS}/{wildcards.scene}/data "
        "--split {input.split} --out-dir {RESULTS}/{wildcards.scene}/models/{wildcards.run} --quiet 2> {log:q}"


# By hand: a job per tool scene, reading every run of the run list, the sessions' raw files and
#   the provenance stamps
rule tool_model_report:
    input:
        runs=lambda w: expand(f"{RESULTS}/{{scene}}/models/{{run}}/{{f}}", scene=w.scene, run=tool_runs(w.scene),
                              f=["eval.json", "predictions.parquet"]),
        splits=lambda w: [f"{RESULTS}/{w.scene}/splits/{run_spec(r)[1]}.json" for r in tool_runs(w.scene)],
        data=rules.tool_dataset.output,
        raw=session_files("tool"),
        code=stage_code("tool-model-report"),
        params=param_stamp("tool-model-report"),
        provenance=lambda w: provenance_inputs(w.scene),
    output:
        metrics=scenes.metric_outputs(f"{RESULTS}/{{scene}}", "tool", P),
        scores=f"{RESULTS}/{{scene}}/scores.json",
        provenance=f"{RESULTS}/{{scene}}/provenance.json",
        runtime=f"{RESULTS}/{{scene}}/runtime.json",
        tables=reported(expand(RESULTS + "/{{scene}}/tables/{t}.md", t=tool_contract.model_tables(P)), "{scene}", "tool"),
        figures=reported(tool_contract.figures(RESULTS + "/{scene}/figures", tool_contract.model_figures(P)), "{scene}", "tool"),
    wildcard_constraints:
        scene="tool_normal|tool_shear",
    params:
        runs=lambda w: tool_runs(w.scene),
        provenance=lambda w: provenance_args(w.scene),
    resources:
        **rule_resources("tool_model_report"),
    log:
        f"{RESULTS}/logs/{{scene}}/model_report.log",
    shell:
        "{CLI} tool-model-report --stamp {input.params:q} --scene {wildcards.scene} --in-dir {RESULTS}/{wildcards.scene} "
        "--runs {params.runs} {params.provenance} 2> {log:q}"
