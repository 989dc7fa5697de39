# Study 000 data stages, shared by the tool_normal (Fz) and tool_shear (Fs) scenes:
# trials (native, public layout or ROS bags) -> one shard per trial -> per-target dataset
# (sync, references, decoded arrays) -> splits, QC report and data figures.

TOOL_TARGETS = {"tool_normal": ("normal", "normal"), "tool_shear": ("shear", "shear")}
TOOL_SPLITS = ["frame", "trial", "loto", "lopo"]


rule simulate_tool:
    output:
        cal="raw/tool/{session}/nano17.cal",
        meta=[f"raw/tool/{{session}}/{name}/meta.json" for name in tool_trial_names("sim-")],
    wildcard_constraints:
        session="sim-[A-Za-z0-9_-]+",
    params:
        physics=P["simulate_tool"],
        seed=P["seed"],
    threads: 2
    log:
        f"{LOGS}/simulate_tool/{{session}}.log",
    shell:
        "{CLI} simulate tool {PARAMS_ARGS} --out-dir raw/tool/{wildcards.session} --jobs {threads} 2> {log}"


rule ingest_tool:
    input:
        tool_trial_input,
    output:
        "results/tool/shards/{session}/{trial}.parquet",
    params:
        fmt=lambda w: tool_trial_format(w.session, w.trial),
        path=lambda w: tool_trial_path(w.session, w.trial),
        ingest=P["tool_ingest"],
    log:
        f"{LOGS}/ingest_tool/{{session}}/{{trial}}.log",
    shell:
        "{CLI} ingest-tool {PARAMS_ARGS} {params.path} --format {params.fmt} --out {output} > {log} 2>&1"


rule tool_dataset:
    input:
        lambda w: tool_shards(TOOL_TARGETS[w.scene][0]),
    output:
        frames="results/{scene}/data/frames.npy",
        references="results/{scene}/data/references.npy",
        samples="results/{scene}/data/samples.parquet",
        qc="results/{scene}/data/qc.json",
    wildcard_constraints:
        scene="tool_normal|tool_shear",
    params:
        kind=lambda w: TOOL_TARGETS[w.scene][0],
        sync=P["tool_sync"],
    log:
        f"{LOGS}/{{scene}}/dataset.log",
    shell:
        "{CLI} tool-dataset {PARAMS_ARGS} --kind {params.kind} --shards {input} "
        "--out-dir results/{wildcards.scene}/data 2> {log}"


rule tool_split:
    input:
        "results/{scene}/data/samples.parquet",
    output:
        "results/{scene}/splits/{split}.json",
    wildcard_constraints:
        scene="tool_normal|tool_shear",
        split="|".join(TOOL_SPLITS),
    params:
        label=lambda w: TOOL_TARGETS[w.scene][1],
        split=P["tool_split"],
        seed=P["seed"],
    log:
        f"{LOGS}/{{scene}}/split_{{split}}.log",
    shell:
        "{CLI} tool-split {PARAMS_ARGS} --data-dir results/{wildcards.scene}/data --split {wildcards.split} "
        "--label {params.label} --out {output} 2> {log}"


rule tool_data_report:
    input:
        data=rules.tool_dataset.output,
        raw=lambda w: tool_raw_inputs(TOOL_TARGETS[w.scene][0]),
    output:
        qc="results/{scene}/qc.md",
        figures=expand("results/{{scene}}/figures/{fig}.png",
                       fig=["force_histogram", "force_profiles", "rmse_vs_force", "pressing_strip"]),
    wildcard_constraints:
        scene="tool_normal|tool_shear",
    params:
        level=P["tool_split"]["level_n"],
    log:
        f"{LOGS}/{{scene}}/data_report.log",
    shell:
        "{CLI} report {wildcards.scene} {PARAMS_ARGS} --in-dir results/{wildcards.scene} 2> {log}"
