# Embedded default data: simulated sessions (raw/<scene>/sim-<scale>/), written as real rigs do.


rule simulate_volume:
    output:
        bags=[f"raw/volume/{{session}}/{stem}.bag" for stem in volume_bag_stems("sim-")],
        labels="raw/volume/{session}/lifts.csv",
    wildcard_constraints:
        session="sim-[A-Za-z0-9_-]+",
    params:
        physics=P["simulate_volume"],
        seed=P["seed"],
    threads: 2
    resources:
        **rule_resources("simulate_volume"),
    log:
        f"{LOGS}/simulate_volume/{{session}}.log",
    shell:
        "{CLI} simulate volume {PARAMS_ARGS} --out-dir raw/volume/{wildcards.session} --labels "
        "--jobs {threads} 2> {log}"


rule simulate_drift:
    output:
        bags=[f"raw/drift/{{session}}/{name}.bag" for name in drift_plan(P)],
    wildcard_constraints:
        session="sim-[A-Za-z0-9_-]+",
    params:
        experiment=P["simulate_drift"],
        physics=P["simulate_volume"],
        seed=P["seed"],
    threads: 2
    resources:
        **rule_resources("simulate_drift"),
    log:
        f"{LOGS}/simulate_drift/{{session}}.log",
    shell:
        "{CLI} simulate drift {PARAMS_ARGS} --out-dir raw/drift/{wildcards.session} --jobs {threads} 2> {log}"
