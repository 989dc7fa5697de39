# Raw recordings -> one validated Parquet shard per bag (only new or changed bags are re-ingested).


rule ingest_papillarray:
    input:
        bag="raw/{scene}/{session}/{stem}.bag",
        code=stage_code("cmd_ingest"),
        params=param_stamp("cmd_ingest"),
    output:
        "results/{scene}/shards/{session}/{stem}.parquet",
    wildcard_constraints:
        scene="volume|drift",
    resources:
        **rule_resources("ingest_papillarray"),
    log:
        f"{LOGS}/ingest/{{scene}}/{{session}}/{{stem}}.log",
    shell:
        "{CLI} ingest {input.bag:q} {output:q} > {log:q} 2>&1"
