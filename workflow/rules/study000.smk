# Study 000 on its own recordings and with its authors' weights (docs/reproduce_study_000.md). Not
# part of the default target, and run from studies/000/ (its own raw/ and results/, so the default
# pipeline's files and dvc.yaml are untouched), with tool_sessions set to public_data.session:
#   study000_protocols  the full model under the public code's frame-level split (leaky: the paper's
#                       protocol) and under our trial split, beside the paper's MAE and R²
#   study000_published  the published normal-force weights over every frame (contaminated)

STUDY000 = f"{RESULTS}/study000"
STUDY000_RUNS = ["full_public_frame", "full_trial"]


# By hand: study000-table makes two rules (a stage declares one), and reads runs of the study's
#   own run list
rule study000_protocols:
    input:
        evals=expand(f"{RESULTS}/tool_normal/models/{{run}}/eval.json", run=STUDY000_RUNS),
        code=stage_code("study000-table"),
        params=param_stamp("study000-table"),
    output:
        table=f"{STUDY000}/protocols.csv",
        markdown=f"{STUDY000}/protocols.md",
        metrics=f"{STUDY000}/metrics.json",
    params:
        out_dir=STUDY000,
    resources:
        **rule_resources("study000_protocols"),
    log:
        f"{LOGS}/study000/protocols.log",
    shell:
        "{CLI} study000-table --stamp {input.params:q} --evals {input.evals:q} --out-dir {params.out_dir:q} 2> {log:q}"


# By hand: reads the published weights under raw/downloads/, outside the build's folder
rule study000_evaluate_published:
    input:
        checkpoint="raw/downloads/best_model_normal.pth",
        data=expand(f"{RESULTS}/tool_normal/data/{{f}}", f=["frames.npy", "references.npy", "samples.parquet"]),
        code=stage_code("tool-evaluate"),
        params=param_stamp("tool-evaluate"),
    output:
        evaluation=f"{STUDY000}/published_normal/eval.json",
        predictions=f"{STUDY000}/published_normal/predictions.parquet",
    params:
        out_dir=f"{STUDY000}/published_normal",
    threads: 2
    resources:
        **rule_resources("study000_evaluate_published"),
    log:
        f"{LOGS}/study000/published_normal.log",
    shell:
        "{CLI} tool-evaluate --stamp {input.params:q} --checkpoint {input.checkpoint:q} --expect best_model_normal --scene tool_normal "
        "--data-dir {RESULTS}/tool_normal/data --all-frames --contaminated --out-dir {params.out_dir:q} > {log:q} 2>&1"


# By hand: study000-table's second rule (see study000_protocols)
rule study000_published:
    input:
        evaluation=rules.study000_evaluate_published.output.evaluation,
        code=stage_code("study000-table"),
        params=param_stamp("study000-table"),
    output:
        table=f"{STUDY000}/published.csv",
        markdown=f"{STUDY000}/published.md",
    params:
        out_dir=STUDY000,
    resources:
        **rule_resources("study000_published"),
    log:
        f"{LOGS}/study000/published.log",
    shell:
        "{CLI} study000-table --stamp {input.params:q} --published {input.evaluation:q} --out-dir {params.out_dir:q} 2> {log:q}"
