# Study 001 under each grasp regime of the simulator (params.yaml volume_regimes), next to the
# paper's Table 1. Not part of the default target: `make regimes` or `snakemake --cores 2 volume_regimes`.

REGIMES = f"{RESULTS}/volume_regimes"


# By hand: its outputs come from params.yaml (a QC file per regime)
rule volume_regimes:
    input:
        code=stage_code("volume-regimes"),
        params=param_stamp("volume-regimes"),
    output:
        table=f"{REGIMES}/table1_regimes.csv",
        markdown=f"{REGIMES}/table1_regimes.md",
        grip=f"{REGIMES}/fz_vs_volume.csv",
        grip_markdown=f"{REGIMES}/fz_vs_volume.md",
        bars=f"{REGIMES}/figures/r2_by_regime.png",
        bars_svg=f"{REGIMES}/figures/r2_by_regime.svg",
        grip_figure=f"{REGIMES}/figures/fz_vs_volume.png",
        grip_figure_svg=f"{REGIMES}/figures/fz_vs_volume.svg",
        metrics=f"{REGIMES}/metrics.json",
        qc=[f"{REGIMES}/qc_{name}.csv" for name in P["volume_regimes"]["regimes"]],
    params:
        out_dir=REGIMES,
    threads: 2
    resources:
        **rule_resources("volume_regimes"),
    log:
        f"{LOGS}/volume_regimes.log",
    shell:
        "{CLI} volume-regimes --stamp {input.params:q} --out-dir {params.out_dir:q} --jobs {threads} 2> {log:q}"
