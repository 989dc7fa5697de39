# Shared set-up: the validated parameters, the sessions and stamps the rules read, how rules call
# the CLI and which files a scene ends in. The logic lives in tactilepipe.pipeline; this wires it.
import atexit
import shlex
import sys
from functools import cache
from pathlib import Path

from tactilepipe import studies
from tactilepipe.pipeline import codedeps, dvc_state, layout, scenes, stage_rules
from tactilepipe.pipeline.sessions import SessionSheet
from tactilepipe.pipeline.stamp_keeper import StampKeeper
from tactilepipe.core.config import changed_leaves, resolve, typed_like
from tactilepipe.core.errors import TactilepipeError
from tactilepipe.core.yamlsafe import load_yaml_file
from tactilepipe.tool import contract as tool_contract, runs as run_names
from tactilepipe.tool.scenes import scene_label
from tactilepipe.tool.sim.background import background_path

# `config` is params.yaml plus any --config overrides; validate and resolve the scale up front
# so a wrong key or type stops the run before any job starts.
_FILE_PARAMS = load_yaml_file("params.yaml")         # its aliases bounded (core/yamlsafe.py)
config.update(typed_like(config, _FILE_PARAMS))
# Overrides given with --config are applied after the scale's overlay; a stage receives the result
# through its parameter stamp (param_stamp), so each sees the same values.
OVERRIDES = changed_leaves(config, _FILE_PARAMS)
try:
    P = resolve(dict(config), "params.yaml (+ --config)", OVERRIDES, studies.CHECKS)   # every study's checks
    # Every recording of the sessions params.yaml names (pipeline/sessions.py), read once per start:
    # a session that cannot be read stops the run here, named, before any job is planned.
    SHEET = SessionSheet(P)
    SHEET.check()
except TactilepipeError as exc:
    raise WorkflowError(str(exc)) from None
CLI = f"{shlex.quote(sys.executable)} -m tactilepipe"
# Every file the workflow writes outside raw/ is under the build's folder (params.yaml `build`, by
# default the scale's name): another scale or build never overwrites these, nor re-runs them.
RESULTS = layout.results_root(P["build"])
LOGS = f"{RESULTS}/logs"
VOLUME = f"{RESULTS}/volume"
DRIFT = f"{RESULTS}/drift"
DRIFT_SESSION = P["drift_session"]


def _tell_snakemake_it_exists(path):
    # Snakemake lists a folder once per start and believes the listing: a stamp written after its
    # folder was listed would otherwise be a missing input (pinned Snakemake's IOCache)
    if workflow.iocache.active:
        workflow.iocache.exists_local[path] = True


# Whether this is a dry run is known only once the graph is built: asked each time a stamp is kept.
STAMPS = StampKeeper(P, SHEET, lambda: workflow.dryrun, _tell_snakemake_it_exists)


onsuccess:
    STAMPS.record_made_files()
    record_for_dvc()                  # workflow/rules/dvc.smk


@cache
def _repo_relative(path):
    """Workflow-relative path of a source file (absolute when the package lives elsewhere)."""
    try:
        return str(Path(path).resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(Path(path).resolve())


def stage_code(stage):
    """Source files the declared stage runs (pipeline/codedeps.py): inputs of its rule, so editing
    one re-runs exactly the rules that run it."""
    return [_repo_relative(codedeps.module_path(m)) for m in sorted(codedeps.stage_modules(stage))]


def param_stamp(stage):
    """An input function giving the stage's parameter stamp (pipeline/stamp_keeper.py): its only
    way to parameters. Kept when the graph is built, the time a dry run is known to be one."""
    codedeps.stage_param_keys(stage)          # an undeclared stage stops the workflow as it is read
    return lambda wildcards: STAMPS.stage(stage)


def run_stamp(wildcards):
    """Input function: the stamp of a training job, its whole run spec."""
    return STAMPS.run("tool", wildcards.run)


def tool_background_frame():
    """The no-contact DIGIT frame the tool simulator draws on: an input, so replacing it re-simulates."""
    return _repo_relative(background_path(P["simulate_tool"]["render"]["background"]))


def rule_resources(rule):
    """What a rule's job asks a scheduler for at this scale: params.yaml `resources` (default, then
    the rule's entry; scales overlay both). mem_mb (MB), runtime (minutes), gpu (0: none)."""
    res = {**P["resources"]["default"], **P["resources"]["rules"].get(rule, {})}
    return {k: v for k, v in res.items() if not (k == "gpu" and v == 0)}


def _print_estimate_after_dry_run():
    # `snakemake -n` runs no hooks (onstart/onsuccess), so the estimate is printed at exit, once
    # the DAG it counts is built; a real run (or a job inside one) prints nothing.
    dag = workflow.dag
    if not workflow.dryrun or dag is None:
        return
    jobs = [(job.rule.name, dict(job.wildcards), dict(job.resources), job.threads)
            for job in dag.needrun_jobs(exclude_finished=False) if not job.is_norun]
    if jobs:
        from tactilepipe.pipeline.estimate import estimate_report
        print(estimate_report(P, jobs, run_spec=run_spec), flush=True)


atexit.register(_print_estimate_after_dry_run)


# --- recordings: each ingest job's inputs, each study's shards and files --------------------------
def simulated_names(study):
    """The recordings a simulator writes (the same names in every simulated session)."""
    return [r.name for r in SHEET.recordings(study, "sim-")]


def shard(r):
    """Where the ingest of recording ``r`` writes its shard."""
    return f"{RESULTS}/{r.study}/shards/{r.session}/{r.name}.parquet"


def shards(study, session=None, kind=None):
    """The shards of a study's recordings (of one session; of one tool trial kind)."""
    return [shard(r) for s in ([session] if session else SHEET.sessions(study))
            for r in SHEET.recordings(study, s) if kind is None or r.kind == kind]


def _recording(w):
    # the ingest rules' wildcards: a tool trial's (found in its session), or a PapillArray bag's,
    # which is its only file (a bag can be ingested from a session params.yaml does not name)
    if "trial" in w.keys():
        return SHEET.recording("tool", w.session, w.trial)
    return SHEET.bag(w.scene, w.session, w.stem)


def ingest_inputs(w):
    """The files a recording's ingest reads (so Snakemake re-ingests exactly those that change)."""
    return SHEET.ingest_inputs(_recording(w))


def content_stamp(w):
    """The content stamp of every file a recording's ingest reads (a simulated one's too)."""
    r = _recording(w)
    return STAMPS.content(r, shard(r))


def session_files(study):
    """Every file of a study's sessions (provenance.json hashes them whole)."""
    return SHEET.study_files(study)


# --- scenes: targets and provenance (pipeline/scenes.py) ----------------------------------------
def scene_targets(names, data_only=False):
    """Every file the scenes end in (a tool scene's data stages only, with ``data_only``)."""
    try:
        return scenes.scene_targets(names, RESULTS, P, SHEET, data_only) + \
            ([] if data_only else stage_rules.declared_outputs(names, RESULTS))
    except TactilepipeError as exc:
        raise WorkflowError(str(exc)) from None


def tool_runs(scene):
    return run_names.tool_runs(P["tool_train"], P["tool_split"]["repeats"], tool_contract.tools(SHEET, scene_label(scene)))


def run_spec(run):
    """(variant, split, depth, image_size) of a run name."""
    return run_names.run_spec(P["tool_train"], run)


def provenance_args(scene):
    """Stages, sessions and the stamps not in the build's folder (a simulator's): what provenance.json records."""
    stages, dirs = scenes.provenance_stages(scene, SHEET)
    return shlex.join(["--provenance-stages", *stages, "--sessions", *dirs, "--provenance-stamps", *STAMPS.scale_stamps(stages)])


def provenance_inputs(scene):
    """The code and parameter stamps of every stage provenance.json can describe: inputs of the
    report, so the record is rewritten whenever what it records changes. The simulator's count
    whether or not a session is simulated, so the graph (and dvc.yaml) does not change with it."""
    stages, _ = scenes.provenance_stages(scene, SHEET, simulator="always")
    runs = tool_runs(scene) if "tool-train" in stages else []     # a stamp per run, none of the stage
    return sorted({f for s in stages for f in stage_code(s)}) + [STAMPS.stage(s) for s in stages if s != "tool-train"] + \
        [STAMPS.run("tool", r) for r in runs]


# `snakemake --report report.html`: every figure, table and metrics file, each with a label and a caption
# saying which data, scale and split it shows (workflow/report/); the front page lists all parameters.
report: "../report/workflow.rst"


def reported(files, scene, study=None):
    """Outputs, those of the report marked as its items (pipeline/scenes.py report_items)."""
    return [f if caption is None else report(f, caption=caption, category=scene, subcategory=kind, labels=labels)
            for f, caption, kind, labels in scenes.report_items(files, study or scene, P)]
