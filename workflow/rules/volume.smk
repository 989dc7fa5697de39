# Study 001: off-table dataset -> folds -> MLP per modality, grid search, baseline -> report.


# By hand: reads every shard and lifts.csv the session sheet names
rule volume_dataset:
    input:
        shards=shards("volume"),
        labels=[f"raw/volume/{s}/lifts.csv" for s in P["volume_sessions"]],
        code=stage_code("volume-dataset"),
        params=param_stamp("volume-dataset"),
    output:
        data=f"{VOLUME}/dataset.parquet",
        qc=f"{VOLUME}/qc.csv",
    resources:
        **rule_resources("volume_dataset"),
    log:
        f"{LOGS}/volume/dataset.log",
    shell:
        "{CLI} volume-dataset --stamp {input.params:q} --shard-root {VOLUME:q}/shards --out {output.data:q} "
        "--qc {output.qc:q} 2> {log:q}"


# By hand: a job per input modality ({modality}) of params.yaml
rule volume_train:
    input:
        data=f"{VOLUME}/dataset.parquet",
        folds=f"{VOLUME}/folds.json",
        code=stage_code("volume-train"),
        params=param_stamp("volume-train"),
    output:
        predictions=f"{VOLUME}/mlp/{{modality}}/predictions.parquet",
        folds=f"{VOLUME}/mlp/{{modality}}/folds.csv",
    params:
        out_dir=lambda w: f"{VOLUME}/mlp/{w.modality}",
    resources:
        **rule_resources("volume_train"),
    log:
        f"{LOGS}/volume/train_{{modality}}.log",
    shell:
        "{CLI} volume-train --stamp {input.params:q} --modality {wildcards.modality:q} --dataset {input.data:q} "
        "--folds {input.folds:q} --out-dir {params.out_dir:q} 2> {log:q}"


# By hand: reads the sessions' shards and raw files and the provenance stamps
rule volume_report:
    input:
        mlp=expand(f"{VOLUME}/mlp/{{modality}}/{{f}}", modality=list(P["mlp"]["modalities"]),
                   f=["predictions.parquet", "folds.csv"]),
        grid=f"{VOLUME}/mlp/grid.csv",
        baseline=rules.volume_baseline.output,      # generated from its declaration (workflow/rules/stages.smk)
        qc=f"{VOLUME}/qc.csv",
        shards=shards("volume"),
        raw=session_files("volume"),
        code=stage_code("volume-report"),
        params=param_stamp("volume-report"),
        provenance=lambda w: provenance_inputs("volume"),
    output:
        reported(scenes.report_outputs("volume", RESULTS, P), "volume"),
    params:
        provenance=lambda w: provenance_args("volume"),
    resources:
        **rule_resources("volume_report"),
    log:
        f"{LOGS}/volume/report.log",
    shell:
        "{CLI} volume-report --stamp {input.params:q} --in-dir {VOLUME:q} --shard-root {VOLUME:q}/shards "
        "{params.provenance} 2> {log:q}"
