"""Generate dvc.yaml from the Snakemake graph: `make dvc.yaml` (or `python workflow/scripts/dvc_yaml.py`).

DVC and Snakemake must agree on what depends on what, so the DVC stages are derived from the jobs
Snakemake plans, never written by hand. The stages themselves, a name and the Snakemake targets
its command builds, are the studies' (their contracts: each simulator's session, SIMULATED_MARK, and
their scenes' DVC_STAGES). For each stage:
- outs: the files its jobs write, each folded into the largest folder that holds nothing but
  this stage's outputs (a recording session at most under raw/); each scene's metrics/ folder is
  the metrics (the headline numbers only, a file per model: core/metric_rows.py), and
  provenance.json, runtime.json and scores.json (every number the report makes) are outs; all
  `cache: false` (kept in git);
- deps: the outputs of other stages its jobs read (as those stages declare them), the raw
  recordings folder of each scene it reads, every source file of the CLI stages its rules run
  (their import closure), and the rule files that define its jobs;
- params: the dotted keys its CLI stages declare and the keys the rules read to shape the graph,
  plus the active scale's overlay (`scales.${scale}`), which may change any of them.

`--check` exits 1 and prints a diff when dvc.yaml differs from what would be generated.
"""

from __future__ import annotations

import argparse
import atexit
import difflib
import io
import json
import re
import sys
from pathlib import Path

import yaml

from tactilepipe.pipeline import codedeps, layout
from tactilepipe.pipeline.stamp_keeper import CONTENT_STAMPS     # the ingest rules' content stamps
from tactilepipe.core.atomic import write_text
from tactilepipe.core.metric_rows import FOLDER as METRICS_FOLDER
from tactilepipe.core.errors import TactilepipeError
from tactilepipe.core.yamlsafe import load_yaml_file
from tactilepipe.studies import contracts

# (name, Snakemake targets) of each DVC stage, from the studies' contracts: each simulator's session
# (the file of it its contract names), then each study's stages of its scenes. "{scale}" is written as
# DVC's ${scale}.
STAGES = [(c.SIMULATOR.replace("-", "_"), [f"raw/{c.STUDY}/sim-{{scale}}/{c.SIMULATED_MARK}"]) for c in contracts().values()] + \
    [(name, targets) for c in contracts().values() for name, targets in c.DVC_STAGES.items()]
if len({name for name, _ in STAGES}) != len(STAGES):
    raise SystemExit(f"two studies' contracts name the same DVC stage: {[name for name, _ in STAGES]}")
# a parameter stamp: a stage's or a training run's (params/tool-train/<run>.json; pipeline/stamp_keeper.py),
# or a dry run's scratch copy of a changed one (changed-params/...)
STAMP = re.compile(r"^(results/[^/]+/params|/.*/changed-params)/([^/]+/)?[^/]+\.json$")
COMMAND = "snakemake --cores 2 --workflow-profile workflow/profiles/default"
# How DVC draws each figure's data (<figure>.csv beside it, each study's contract.py PLOT_DATA): columns
# as the figure modules write them, and one of DVC's own vega-lite templates
DATA_PLOTS = {
    "mu_r2_curve.csv": {"x": "mu", "y": ["r2_train_mean", "r2_train_min", "r2_train_max"], "template": "linear",
                        "title": "volume baseline: R2 of the training folds against the friction coefficient mu"},
    "drift_curves.csv": {"x": "t_min", "y": ["unloaded_drift_n", "loaded_drift_n"], "template": "linear",
                         "title": "PapillArray drift of global Fz since the bias request (N) against minutes"},
    "error_vs_runtime.csv": {"x": "train_s", "y": "mae", "template": "scatter",
                             "title": "{scene}: test MAE (N) against training wall time (s), every run"},
    "intervals.csv": {"x": "mae_mean", "y": "model", "template": "bar_horizontal",
                      "title": "{scene}: mean test MAE (N) over the repeated splits, per variant and baseline"},
}


def is_metric(f: str) -> bool:
    """A file DVC shows as metrics: a scene's metric row (metrics/<row>.json, core/metric_rows.py).
    Study 000's stages below declare their own metrics.json."""
    path = Path(f)
    return path.suffix == ".json" and path.parent.name == METRICS_FOLDER


# kept in git beside the metrics, but not metrics: what made them (provenance), how long it took
# (run times change on every run) and every number behind the headline (scores.json)
UNCACHED_OUTS = {"provenance.json", "runtime.json", "scores.json"}
ALWAYS_RULE_FILES = ["Snakefile", "workflow/rules/common.smk"]


def workflow_library() -> list[str]:
    """The workflow's own library: the modules of tactilepipe.pipeline that common.smk imports, and
    those they import from it (the session sheet, the scenes, the stamps, the declared rules), with
    the studies' contracts they read (tactilepipe/studies.py, each study's contract.py and their
    vocabulary, core/study.py). Its logic is the rule files', and an edit to it can change any
    stage's jobs: a dep of every stage, as common.smk is. (Study modules they call are the code of
    the stages that run them.)"""
    text = Path("workflow/rules/common.smk").read_text()
    roots = {"tactilepipe.studies"} if re.search(r"^from tactilepipe import studies$", text, flags=re.M) else set()
    for sub, names in re.findall(r"^from tactilepipe\.pipeline(?:\.(\w+))? import ([\w, ]+)$", text, flags=re.M):
        roots |= {f"tactilepipe.pipeline.{sub}"} if sub else {f"tactilepipe.pipeline.{n.strip()}" for n in names.split(",")}
    modules = {m for r in roots for m in codedeps.module_closure(r) if m.startswith("tactilepipe.pipeline.")
               or m in ("tactilepipe.studies", "tactilepipe.core.study") or m.endswith(".contract")}
    return sorted(str(codedeps.module_path(m).resolve().relative_to(Path.cwd().resolve())) for m in modules)


HEADER = """\
# GENERATED from the Snakemake graph by `make dvc.yaml` (workflow/scripts/dvc_yaml.py): do not edit.
# Each stage runs Snakemake targets, so the logic exists once (workflow/rules); its deps are the
# data it reads, the source files of the code it runs and its rule files; its params the keys
# that code declares. tests/integration/test_dvc_graph.py fails when this file is not what the
# generator makes.
"""


def build_jobs(targets: list[str]):
    """Every job Snakemake plans for ``targets`` (forced, so up-to-date jobs are listed too)."""
    from snakemake.api import SnakemakeApi
    from snakemake.settings.enums import Quietness
    from snakemake.settings.types import ConfigSettings, DAGSettings, OutputSettings, ResourceSettings

    with SnakemakeApi(OutputSettings(quiet={Quietness.ALL})) as api:
        wapi = api.workflow(resource_settings=ResourceSettings(cores=1), config_settings=ConfigSettings(),
                            snakefile=Path("Snakefile"), workdir=Path.cwd())
        wapi.dag(DAGSettings(targets=set(targets), forceall=True))
        # The public API plans and runs; the plan alone is on the workflow object (pinned version).
        wf = wapi._workflow
        # planned as a dry run, so the workflow writes no stamp (a changed one goes to its scratch folder)
        wf.__class__ = type("PlanOnly", (type(wf),), {"dryrun": property(lambda self: True)})
        wf._prepare_dag(forceall=True, ignore_incomplete=True, lock_warn_only=True, nolock=True)
        wf._build_dag()
        dag = wf.dag
        atexit.unregister(wf.globals["_print_estimate_after_dry_run"])    # that is for a user's dry run
        return list(dag.jobs), dag.dependencies


def stage_of_jobs(jobs, dependencies, targets_of: dict[str, list[str]]) -> dict:
    """{job: stage}: each job belongs to the first stage (in STAGES order) whose targets need it."""
    by_output = {str(f): j for j in jobs for f in j.output}
    by_rule = {}
    for j in jobs:
        by_rule.setdefault(j.rule.name, []).append(j)
    owner = {}
    for stage, targets in targets_of.items():
        todo = [by_output[t] if t in by_output else by_rule[t][0] for t in targets]
        while todo:
            j = todo.pop()
            if j in owner:
                continue
            owner[j] = stage
            todo.extend(dependencies[j])
    return owner


def _under(path: str, folder: str) -> bool:
    return path == folder or path.startswith(folder.rstrip("/") + "/")


def fold_outputs(files: list[str], stage: str, output_stage: dict[str, str]) -> list[str]:
    """Each output file of ``stage`` folded into the largest folder whose outputs are all this
    stage's and hold no metrics or run-time files (those are declared on their own)."""
    special = {f for f in output_stage if (is_metric(f) or Path(f).name in UNCACHED_OUTS)}

    def owned(folder: str) -> bool:
        inside = [f for f in output_stage if _under(f, folder)]
        return all(output_stage[f] == stage for f in inside) and not any(_under(f, folder) for f in special)

    entries = set()
    for f in files:
        entry, parts = f, Path(f).parts
        limit = 3 if parts[0] == "raw" else 4            # raw/<scene>/<session>, results/<build>/<scene>/<step>
        for depth in range(len(parts) - 1, limit - 1, -1):
            folder = str(Path(*parts[:depth]))
            if not owned(folder):
                break
            entry = folder
        entries.add(entry)
    return sorted(entries)


def results_folders(params: dict) -> tuple[str, str]:
    """The build's results folder as Snakemake writes it for params.yaml's scale (results/default),
    and as dvc.yaml names it, so that the stages follow the scale DVC is given (results/${scale})."""
    build = params.get("build", "{scale}")
    return (layout.results_root(build.replace("{scale}", str(params["scale"]))),
            layout.results_root(build.replace("{scale}", "${scale}")))


def generate(params: dict) -> str:
    scale = params["scale"]
    root, dvc_root = results_folders(params)
    targets_of = {name: [t.replace("{scale}", scale).replace("{results}", root) for t in targets]
                  for name, targets in STAGES}
    jobs, dependencies = build_jobs([t for ts in targets_of.values() for t in ts])
    owner = stage_of_jobs(jobs, dependencies, targets_of)
    output_stage = {str(f): owner[j] for j in jobs if j in owner for f in j.output}
    sim = f"sim-{scale}"

    def dvc_path(path: str) -> str:
        if _under(path, root):
            path = dvc_root + path[len(root):]
        return re.sub(rf"(?<![A-Za-z0-9-]){re.escape(sim)}(?![A-Za-z0-9-])", "sim-${scale}", path)

    folded = {name: fold_outputs([f for f, s in output_stage.items() if s == name
                                  and not (is_metric(f) or Path(f).name in UNCACHED_OUTS)], name, output_stage)
              for name, _ in STAGES}
    doc = {"stages": {}}
    plots = []
    library = workflow_library()                        # the same for every stage
    for name, targets in STAGES:
        own = [j for j in jobs if owner.get(j) == name]
        deps, code, rule_files, keys = set(), set(), set(ALWAYS_RULE_FILES), {"scale"}
        code.update(library)
        for j in own:
            rule_files.add(str(Path(j.rule.snakefile).resolve().relative_to(Path.cwd().resolve())))
            # a rule's stamps name the CLI stages whose code and parameters it depends on (its own,
            # and for a report those its provenance records): its code inputs must be their closure
            stamps = [json.loads(Path(f).read_text()) for f in {str(f) for f in j.input}
                      if STAMP.match(f)]
            expected = {f for stamp in stamps for f in codedeps.stage_files(stamp["stage"], Path.cwd())}
            if {str(f) for f in j.input if str(f).endswith(".py")} != expected:
                raise SystemExit(f"rule {j.rule.name}: its code inputs are not the closure of the stages "
                                 f"{sorted(s['stage'] for s in stamps)}")
            for stamp in stamps:
                keys.update(stamp["declared"] + stamp["graph"])
            # a target rule (a scene's, `all`) writes nothing: what it gathers is its stages' outs, or
            # another stage's, and no dependency of this one
            for f in map(str, j.input if j.output else ()):
                if STAMP.match(f):
                    continue                      # DVC reads the same values from params.yaml
                if f.startswith(CONTENT_STAMPS + "/") or "/changed-content/" in f:
                    continue                      # DVC hashes the raw/ folders' content itself
                if f.endswith(".py"):
                    code.add(f)
                elif output_stage.get(f) == name:
                    continue
                elif f.startswith("raw/"):
                    deps.add("/".join(Path(f).parts[:2]))
                elif f in output_stage:
                    deps.add(next(o for o in folded[output_stage[f]] if _under(f, o)))
                else:
                    deps.add(f)
        outs = folded[name]
        special = sorted(f for f, s in output_stage.items() if s == name and (is_metric(f) or Path(f).name in UNCACHED_OUTS))
        stage = {"cmd": f"{COMMAND} " + " ".join(t.replace("{scale}", "${scale}").replace("{results}", dvc_root)
                                                 for t in targets),
                 "deps": sorted(map(dvc_path, deps)) + sorted(code) + sorted(rule_files),
                 "params": _outermost(keys) + ["scales.${scale}"]}
        # sessions, shards and trained models are kept while a stage re-runs: Snakemake inside it
        # rebuilds exactly the out-of-date ones (persist), which is what makes a new session cheap
        stage["outs"] = [{dvc_path(o): {"persist": True}} if _persisted(o) else dvc_path(o) for o in outs]
        stage["outs"] += [{dvc_path(f): {"cache": False}} for f in special if Path(f).name in UNCACHED_OUTS]
        # a scene's metric rows as their folder: DVC shows each file in it as a row, and a row that
        # comes or goes with params.yaml (a variant, an input) needs no new dvc.yaml
        metrics = [{dvc_path(f): {"cache": False}} for f in sorted({str(Path(f).parent) for f in special if is_metric(f)})]
        if metrics:
            stage["metrics"] = metrics
        doc["stages"][name] = stage
        # the figures of a scene (a session's QC figures are outs, not plots: their names change with
        # sessions) as images, then the data of those that write it, which `dvc plots diff` overlays
        figures = [f for f, s in output_stage.items() if s == name and "/figures/" in f]
        plots += sorted(dvc_path(f) for f in figures if f.endswith(".png"))
        plots += [{dvc_path(f): data_plot(f)} for f in sorted(figures) if f.endswith(".csv")]
    doc["plots"] = plots
    out = io.StringIO()
    out.write(HEADER)
    yaml.safe_dump(doc, out, sort_keys=False, width=110)
    return out.getvalue()


STUDY000 = "studies/000/dvc.yaml"
STUDY000_HEADER = """\
# GENERATED by `make dvc.yaml` (workflow/scripts/dvc_yaml.py, study000()): do not edit.
# Study 000 on its own recordings and with its authors' weights: opt-in, never part of `make run` or
# of the project's dvc.yaml (docs/reproduce_study_000.md). This folder is a DVC project of its own
# (`dvc init --subdir`: own cache, not seen by the project's `dvc status`, `push` or `pull`), with
# its own raw/ and results/; params.yaml is the project's (a link). First `make study000-import`
# (dvc import-url of the four files into raw/downloads/), then fill in raw/tool/public/trials.csv.
# The unpack stages run the CLI (Snakemake lists trials from disk, so they must exist first); the
# others run Snakemake targets of workflow/rules/study000.smk and tool.smk. Code deps: the source
# files of the CLI stages each one runs (their import closure), as in the project's dvc.yaml.
"""
SMK = "snakemake -s ../../Snakefile --cores 2 --workflow-profile ../../workflow/profiles/default " \
      "--config 'tool_sessions=[\"${public_data.session}\"]' --"
RULE_FILES = ["../../Snakefile", "../../workflow/rules"]


def study000(params: dict) -> str:
    """studies/000/dvc.yaml: its stages, with the exact source files of the CLI stages they run."""
    def code(*stages: str) -> list[str]:
        return sorted({f"../../{f}" for s in stages for f in codedeps.stage_files(s, Path.cwd())})

    session = "raw/tool/${public_data.session}"
    res = results_folders(params)[1]                # the build's folder, as DVC names it (results/${scale})
    stages = {}
    for kind in ("normal", "shear"):
        stages[f"unpack_{kind}"] = {
            "cmd": f"tactilepipe study000-unpack raw/downloads/data_{kind}.zip --name data_{kind}",
            "deps": [f"raw/downloads/data_{kind}.zip"] + code("study000-unpack"),
            "params": [f"public_data.files.data_{kind}", "public_data.session"],
            "outs": [f"{session}/data_{kind}"]}
    data_stages = ("tool-ingest", "tool-dataset", "tool-split")
    stages["data"] = {
        "cmd": f"{SMK} {res}/tool_normal/data/samples.parquet {res}/tool_normal/splits/public_frame.json "
               f"{res}/tool_normal/splits/trial.json",
        "deps": [f"{session}/data_normal", f"{session}/trials.csv"] + code(*data_stages) + RULE_FILES,
        "params": ["scale", "seed", "tool_ingest", "tool_sync", "tool_split", "scales.${scale}"],
        "outs": [{f"{res}/tool/shards": {"persist": True}}, f"{res}/tool_normal/data", f"{res}/tool_normal/splits"]}
    stages["protocols"] = {
        "cmd": f"{SMK} study000_protocols",
        "deps": [f"{res}/tool_normal/data", f"{res}/tool_normal/splits"]
                + code("tool-train", "study000-table") + RULE_FILES,
        "params": ["scale", "seed", "tool_train", "public_data.paper", "scales.${scale}"],
        "outs": [{f"{res}/tool_normal/models": {"persist": True}}, f"{res}/study000/protocols.csv",
                 f"{res}/study000/protocols.md"],
        "metrics": [{f"{res}/study000/metrics.json": {"cache": False}}]}
    stages["published"] = {
        "cmd": f"{SMK} study000_published",
        "deps": ["raw/downloads/best_model_normal.pth", f"{res}/tool_normal/data"]
                + code("tool-evaluate", "study000-table") + RULE_FILES,
        "params": ["tool_train.device", "public_data.files.best_model_normal", "public_data.paper"],
        "outs": [f"{res}/study000/published_normal", f"{res}/study000/published.csv",
                 f"{res}/study000/published.md"]}
    out = io.StringIO()
    out.write(STUDY000_HEADER)
    yaml.safe_dump({"stages": stages}, out, sort_keys=False, width=110)
    return out.getvalue()


def data_plot(path: str) -> dict:
    """The plot definition of a figure's data file (DATA_PLOTS), titled with its scene."""
    if Path(path).name not in DATA_PLOTS:
        raise SystemExit(f"{path}: a figure's data with no plot definition: add it to DATA_PLOTS")
    spec = dict(DATA_PLOTS[Path(path).name])
    spec["title"] = spec["title"].format(scene=Path(path).parent.parent.name)
    return spec


def _outermost(keys: set[str]) -> list[str]:
    """Sorted keys without those inside another listed key ("mlp.tol" goes when "mlp" is there)."""
    return sorted(k for k in keys if not any(k.startswith(other + ".") for other in keys))


def _persisted(out: str) -> bool:
    """Outputs made per recording session or per run (the raw sessions, shards, each session's clock
    figure under tool/qc/, the trained models): DVC keeps them for Snakemake to rebuild the out-of-date
    ones, so that a new session re-runs its own jobs only, in `dvc repro` as in `snakemake`."""
    parts = Path(out).parts
    return parts[0] == "raw" or "shards" in parts or "models" in parts or "qc" in parts


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 with a diff if dvc.yaml is not generated")
    parser.add_argument("--out", default="dvc.yaml")
    parser.add_argument("--study000", action="store_true", help="only studies/000/dvc.yaml (no Snakemake graph)")
    args = parser.parse_args(argv)
    params = load_yaml_file("params.yaml")
    targets = [(STUDY000, lambda: study000(params))]
    if not args.study000:
        targets.insert(0, (args.out, lambda: generate(params)))
    status = 0
    for path, make in targets:
        text = make()
        current = Path(path).read_text() if Path(path).exists() else ""
        if args.check:
            if text != current:
                sys.stdout.writelines(difflib.unified_diff(current.splitlines(True), text.splitlines(True),
                                                           f"{path} (committed)", f"{path} (generated)"))
                print(f"\n{path} is not what the generator gives: run `make dvc.yaml` and commit it.")
                status = 1
        elif text != current:
            write_text(path, text)
    return status


if __name__ == "__main__":
    try:
        sys.exit(main())
    except TactilepipeError as exc:
        sys.exit(f"dvc_yaml: error: {exc}")
