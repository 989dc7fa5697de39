# Raw recordings -> one validated Parquet shard per bag (only new or changed bags are re-ingested).

# A PapillArray bag takes about a second and 140 MB to ingest (a default-scale lift), less than the
# two Snakemake starts a SLURM job costs: on a cluster these run where Snakemake runs, instead of
# queueing as one job per bag (the volume and drift sessions are most of the jobs).
localrules:
    papillarray_ingest,


# By hand: a job per recording of the session sheet ({scene}/{session}/{stem})
rule papillarray_ingest:
    input:
        bag="raw/{scene}/{session}/{stem}.bag",
        content=content_stamp,
        code=stage_code("papillarray-ingest"),
        params=param_stamp("papillarray-ingest"),
    output:
        f"{RESULTS}/{{scene}}/shards/{{session}}/{{stem}}.parquet",
    wildcard_constraints:
        scene="volume|drift",
    resources:
        **rule_resources("papillarray_ingest"),
    log:
        f"{LOGS}/ingest/{{scene}}/{{session}}/{{stem}}.log",
    shell:
        "{CLI} papillarray-ingest {input.bag:q} {output:q} > {log:q} 2>&1"
