# Study 001's drift experiment: recordings every 5 min over 30 min -> drift curves and fits.


rule drift_report:
    input:
        drift_shards(),
    output:
        reported(DRIFT_TARGETS, "drift"),
        series=f"{DRIFT}/drift_series.csv",
        fits=f"{DRIFT}/fits.csv",
    params:
        drift=P["drift"],
    resources:
        **rule_resources("drift_report"),
    log:
        f"{LOGS}/drift/report.log",
    shell:
        "{CLI} report drift {PARAMS_ARGS} --in-dir {DRIFT} --shards {input} 2> {log}"
