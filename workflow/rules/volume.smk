# Study 001: off-table dataset -> folds -> MLP per modality, grid search, baseline -> report.


rule volume_dataset:
    input:
        shards=volume_shards(),
        labels=[f"raw/volume/{s}/lifts.csv" for s in P["volume_sessions"]],
    output:
        data=f"{VOLUME}/dataset.parquet",
        qc=f"{VOLUME}/qc.csv",
    params:
        segment=P["segment"],
        sessions=P["volume_sessions"],
    resources:
        **rule_resources("volume_dataset"),
    log:
        f"{LOGS}/volume/dataset.log",
    shell:
        "{CLI} dataset {PARAMS_ARGS} --out {output.data} --qc {output.qc} 2> {log}"


rule volume_split:
    input:
        f"{VOLUME}/dataset.parquet",
    output:
        f"{VOLUME}/folds.json",
    params:
        folds=P["folds"],
        seed=P["seed"],
    resources:
        **rule_resources("volume_split"),
    log:
        f"{LOGS}/volume/split.log",
    shell:
        "{CLI} split {PARAMS_ARGS} --dataset {input} --out {output} 2> {log}"


rule volume_train:
    input:
        data=f"{VOLUME}/dataset.parquet",
        folds=f"{VOLUME}/folds.json",
    output:
        predictions=f"{VOLUME}/mlp/{{modality}}/predictions.parquet",
        folds=f"{VOLUME}/mlp/{{modality}}/folds.csv",
    params:
        mlp=lambda w: {k: v for k, v in P["mlp"].items() if k not in ("grid", "modalities")},
        axes=lambda w: P["mlp"]["modalities"][w.modality],
        sensor=P["volume_sensor"],
    resources:
        **rule_resources("volume_train"),
    log:
        f"{LOGS}/volume/train_{{modality}}.log",
    shell:
        "{CLI} train {PARAMS_ARGS} --modality {wildcards.modality} --dataset {input.data} "
        "--folds {input.folds} --out-dir {VOLUME}/mlp/{wildcards.modality} 2> {log}"


rule volume_gridsearch:
    input:
        data=f"{VOLUME}/dataset.parquet",
        folds=f"{VOLUME}/folds.json",
    output:
        f"{VOLUME}/mlp/grid.csv",
    params:
        mlp=P["mlp"],
        sensor=P["volume_sensor"],
    resources:
        **rule_resources("volume_gridsearch"),
    log:
        f"{LOGS}/volume/gridsearch.log",
    shell:
        "{CLI} gridsearch {PARAMS_ARGS} --dataset {input.data} --folds {input.folds} --out {output} 2> {log}"


rule volume_baseline:
    input:
        data=f"{VOLUME}/dataset.parquet",
        folds=f"{VOLUME}/folds.json",
    output:
        predictions=f"{VOLUME}/baseline/predictions.parquet",
        folds=f"{VOLUME}/baseline/folds.csv",
        curve=f"{VOLUME}/baseline/mu_curve.csv",
        mu=f"{VOLUME}/baseline/mu.json",
    params:
        baseline=P["baseline"],
        sensor=P["volume_sensor"],
    resources:
        **rule_resources("volume_baseline"),
    log:
        f"{LOGS}/volume/baseline.log",
    shell:
        "{CLI} baseline {PARAMS_ARGS} --dataset {input.data} --folds {input.folds} "
        "--out-dir {VOLUME}/baseline 2> {log}"


rule volume_report:
    input:
        mlp=expand(f"{VOLUME}/mlp/{{modality}}/{{f}}", modality=list(P["mlp"]["modalities"]),
                   f=["predictions.parquet", "folds.csv"]),
        grid=f"{VOLUME}/mlp/grid.csv",
        baseline=rules.volume_baseline.output,
        qc=f"{VOLUME}/qc.csv",
        shards=volume_shards(),
    output:
        reported(VOLUME_TARGETS, "volume"),
    resources:
        **rule_resources("volume_report"),
    log:
        f"{LOGS}/volume/report.log",
    shell:
        "{CLI} report volume {PARAMS_ARGS} --in-dir {VOLUME} 2> {log}"
