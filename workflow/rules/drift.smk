# Study 001's drift experiment: recordings every 5 min over 30 min -> drift curves and fits.


# By hand: reads the session's shards, raw files and session.json, and the provenance stamps
rule drift_report:
    input:
        shards=shards("drift"),
        meta=f"raw/drift/{DRIFT_SESSION}/session.json",
        code=stage_code("drift-report"),
        params=param_stamp("drift-report"),
        raw=session_files("drift"),
        provenance=lambda w: provenance_inputs("drift"),
    output:
        reported(scenes.report_outputs("drift", RESULTS, P), "drift"),
        series=f"{DRIFT}/drift_series.csv",
        fits=f"{DRIFT}/fits.csv",
    params:
        provenance=lambda w: provenance_args("drift"),
    resources:
        **rule_resources("drift_report"),
    log:
        f"{LOGS}/drift/report.log",
    shell:
        "{CLI} drift-report --stamp {input.params:q} --in-dir {DRIFT:q} --session-meta {input.meta:q} "
        "--shards {input.shards:q} {params.provenance} 2> {log:q}"
