# Embedded default data: simulated sessions (raw/<scene>/sim-<scale>/), written as real rigs do.


# By hand: writes a session under raw/, outside the build's folder, from its scale's stamp; made
#   in a loop, the simulators' rules changed their recorded commands (decision 0035)
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


# By hand: writes a session under raw/ from its scale's stamp, as volume_simulate does
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
