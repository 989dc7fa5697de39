# Embedded default data: simulated sessions (raw/<scene>/sim-<scale>/), written as real rigs do.


rule volume_simulate:
    input:
        code=stage_code("volume-simulate"),
        params=param_stamp("volume-simulate"),
    output:
        bags=[f"raw/volume/{{session}}/{stem}.bag" for stem in simulated_names("volume")],
        labels="raw/volume/{session}/lifts.csv",
    wildcard_constraints:
        session="sim-[A-Za-z0-9_-]+",
    params:
        out_dir=lambda w: f"raw/volume/{w.session}",
    threads: 2
    resources:
        **rule_resources("volume_simulate"),
    log:
        f"{LOGS}/volume_simulate/{{session}}.log",
    shell:
        "{CLI} volume-simulate --stamp {input.params:q} --out-dir {params.out_dir:q} --labels --jobs {threads} 2> {log:q}"


rule drift_simulate:
    input:
        code=stage_code("drift-simulate"),
        params=param_stamp("drift-simulate"),
    output:
        bags=[f"raw/drift/{{session}}/{name}.bag" for name in simulated_names("drift")],
        meta="raw/drift/{session}/session.json",
    wildcard_constraints:
        session="sim-[A-Za-z0-9_-]+",
    params:
        out_dir=lambda w: f"raw/drift/{w.session}",
    threads: 2
    resources:
        **rule_resources("drift_simulate"),
    log:
        f"{LOGS}/drift_simulate/{{session}}.log",
    shell:
        "{CLI} drift-simulate --stamp {input.params:q} --out-dir {params.out_dir:q} --jobs {threads} 2> {log:q}"
