# Shared set-up: the validated parameters, how rules call the CLI, and which files a scene needs.
import atexit
import json
import shlex
import sys
from functools import cache
from pathlib import Path

import yaml

from tactilepipe.pipeline import codedeps, layout, manifest, stamps, studies
from tactilepipe.core.atomic import write_text
from tactilepipe.core.config import changed_leaves, resolve, typed_like
from tactilepipe.core.errors import TactilepipeError
from tactilepipe.volume.labels import read_session_labels
from tactilepipe.volume.simulate import session_plan
from tactilepipe.drift.simulate import session_plan as drift_plan
from tactilepipe.tool.formats.trials import list_trials as list_tool_trials, public_trial_meta, read_trials_csv, trial_files
from tactilepipe.tool.sim import session_plan as tool_plan
from tactilepipe.tool import runs as run_names
from tactilepipe.tool.scenes import scene_label
from tactilepipe.tool.data.splits import split_name
from tactilepipe.tool.sim.background import background_path

# `config` is params.yaml plus any --config overrides; validate and resolve the scale up front
# so a wrong key or type stops the run before any job starts.
with open("params.yaml") as _fh:
    _FILE_PARAMS = yaml.safe_load(_fh)
config.update(typed_like(config, _FILE_PARAMS))
# Overrides given with --config are applied after the scale's overlay; a stage receives the result
# through its parameter stamp (param_stamp), so each sees the same values.
OVERRIDES = changed_leaves(config, _FILE_PARAMS)
try:
    P = resolve(dict(config), "params.yaml (+ --config)", OVERRIDES, studies.CHECKS)   # every study's checks
except TactilepipeError as exc:
    raise WorkflowError(str(exc)) from None
CLI = f"{shlex.quote(sys.executable)} -m tactilepipe"
# Every file the workflow writes outside raw/ is under the build's folder (params.yaml `build`, by
# default the scale's name): another scale or build never overwrites these, nor re-runs them.
RESULTS = layout.results_root(P["build"])


@cache
def _repo_relative(path):
    """Workflow-relative path of a source file (absolute when the package lives elsewhere)."""
    try:
        return str(Path(path).resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(Path(path).resolve())


def stage_code(stage):
    """Source files the declared stage ``stage`` (a command name) runs (its import closure in tactilepipe): a
    rule lists them as inputs, so editing one re-runs exactly the rules that run it."""
    return [_repo_relative(codedeps.module_path(m)) for m in sorted(codedeps.stage_modules(stage))]


def tool_background_frame():
    """The no-contact DIGIT frame the tool simulator draws on (simulate_tool.render.background, or
    the one shipped with the package): an input, so replacing the file re-runs the simulator."""
    return _repo_relative(background_path(P["simulate_tool"]["render"]["background"]))


PARAM_STAMPS = f"{RESULTS}/params"
# The simulators write raw/<scene>/sim-<scale>/, which every build of the scale reads: their stamps
# belong to the scale (results/<scale>/params/), so a second build of one scale re-simulates nothing.
SCALE_STAMPS = f"{layout.results_root(P['scale'])}/params"
SCALE_STAGES = {"volume-simulate", "drift-simulate", "tool-simulate"}


def param_stamp(stage):
    """An input function giving results/<build>/params/<stage>.json: the values of the parameters the stage
    declares (its only way in) and of its declared graph keys, the ones the rules read to decide
    which jobs exist or what their commands say (both from its `@command` declaration). Rewritten
    only when the values change: a change then re-runs the rule by file time, also where Snakemake
    has no record of earlier runs (a fresh clone, a new machine), which its params trigger needs.
    Versioned by git beside the metrics; the dvc.yaml generator reads the stage and the keys from it.

    Evaluated when the graph is built, not when the Snakefile is read, because only then does
    Snakemake say whether this is a dry run: a dry run must not rewrite a tracked stamp, so a
    changed one is written to a scratch folder outside the project instead. Its newer time plans
    the same re-run, and Snakemake's reason names it (``changed-params/<stage>.json``)."""
    codedeps.stage_param_keys(stage)          # an undeclared stage stops the workflow as it is read
    return lambda wildcards: stamp_file(stage)


@cache
def stamp_file(stage):
    """The stamp of ``stage`` as this run sees it (see param_stamp): the tracked file, written when
    its values changed, or in a dry run a scratch copy holding the new values."""
    text = stamps.stamp_text(stage, codedeps.stage_param_keys(stage), codedeps.stage_graph_keys(stage), P)
    return _current_stamp(Path(SCALE_STAMPS if stage in SCALE_STAGES else PARAM_STAMPS), f"{stage}.json", text)


def run_stamp(wildcards):
    """Input function: the stamp of a training job, results/<build>/params/tool-train/<run>.json."""
    return run_stamp_file(wildcards.run)


@cache
def run_stamp_file(run):
    """A training job's own stamp (pipeline/stamps.py run_stamp_text): the values of the tool-train
    stage's declared keys and the run's definition (tool/runs.py run_definition), kept like a stage
    stamp (see stamp_file). A key only some runs read, or a new variant, re-runs only those runs."""
    text = stamps.run_stamp_text(run_names.run_definition(P, run), codedeps.stage_param_keys("tool-train"),
                                 run_names.run_source_keys(P["tool_train"], run), P)
    return _current_stamp(Path(PARAM_STAMPS), f"tool-train/{run}.json", text)


def _current_stamp(folder, name, text):
    """folder/name holding ``text``: left alone when it already does, else rewritten, or in a dry run
    written to the scratch folder instead (its path returned)."""
    path = folder / name
    old = path.read_text() if path.is_file() else None
    if old == text:
        return str(path)
    print(f"{path}: {stamps.stamp_change(old, text)}", file=sys.stderr, flush=True)
    if workflow.dryrun:
        path = Path(_dry_run_scratch()) / "changed-params" / name
        path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, text)
    _tell_snakemake_it_exists(path)
    return str(path)


CONTENT_STAMPS = ".tactilepipe/content"


@cache
def content_stamp(scene, session, unit, files, output, trial=None):
    """An input of the job that ingests ``files`` (a tuple, of raw/<scene>/<session>) into
    ``output``: a stamp of their content hashes, rewritten when one changes and dated when the
    change reached the disk, so a file changed with its old time kept (cp -p, rsync -t, cp -a)
    re-runs the job (pipeline/manifest.py). Local state, not versioned; a dry run writes nothing.
    ``trial``: a tool trial whose files are listed from the disk (tool_trial_files), again once they exist."""
    name = f"{scene}/{session}/{unit}.json"
    scratch = Path(_dry_run_scratch()) / "changed-content" / name if workflow.dryrun else None
    stamp, found = f"{CONTENT_STAMPS}/{name}", _session_manifest(f"raw/{scene}/{session}")
    path, change = manifest.update_stamp(stamp, found, list(files), output, dry_run_copy=scratch)
    if change:
        print(f"{CONTENT_STAMPS}/{name}: {change}", file=sys.stderr, flush=True)
    if not workflow.dryrun and manifest.holds_absent(path):
        _STAMPS_OF_ABSENT_FILES.append((stamp, found, files, output, trial))
    _tell_snakemake_it_exists(path)
    return str(path)


# Stamps of files that did not exist yet when the run planned its jobs (a session this run
# simulates). Recorded once the run has made them, so the first edit after this run is a change.
_STAMPS_OF_ABSENT_FILES = []


onsuccess:
    for stamp, found, files, output, trial in _STAMPS_OF_ABSENT_FILES:
        manifest.update_stamp(stamp, found, list(tool_trial_files(*trial) if trial else files), output)


@cache
def _session_manifest(folder):
    found = manifest.SessionManifest(folder)
    atexit.register(found.save)               # the hash cache is written once, as Snakemake exits
    return found


def _tell_snakemake_it_exists(path):
    # Snakemake lists a folder once per start and believes the listing: a stamp written after its
    # folder was listed would otherwise be a missing input (pinned Snakemake's IOCache)
    if workflow.iocache.active:
        workflow.iocache.exists_local[str(path)] = True


@cache
def _dry_run_scratch():
    import shutil
    import tempfile
    folder = tempfile.mkdtemp(prefix="tactilepipe-dry-run-")
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    return folder


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
        print(estimate_report(P, jobs, run_spec=globals().get("run_spec")), flush=True)


atexit.register(_print_estimate_after_dry_run)

LOGS = f"{RESULTS}/logs"
VOLUME = f"{RESULTS}/volume"
DRIFT = f"{RESULTS}/drift"
DRIFT_SESSION = P["drift_session"]


def is_simulated(session):
    return session.startswith("sim-")


# The session lists below are asked for once per job while Snakemake builds its graph; each is
# computed once per Snakemake start (`cache`). Nothing in the workflow writes into a real
# session's folder, and a simulated session's names come from its plan, not from the disk.


@cache
def volume_bag_stems(session):
    """Bags of a volume session: planned by the simulator, or listed in the session's lifts.csv."""
    if is_simulated(session):
        return tuple(lift.name for lift in session_plan(P["simulate_volume"]))
    return tuple(Path(row["bag"]).stem for row in read_session_labels(f"raw/volume/{session}"))


def volume_shards():
    return [f"{VOLUME}/shards/{s}/{stem}.parquet" for s in P["volume_sessions"] for stem in volume_bag_stems(s)]


@cache
def drift_bag_stems(session):
    """Bags of the drift session: planned by the simulator, or the .bag files in its folder."""
    if is_simulated(session):
        return tuple(drift_plan(P))
    stems = tuple(sorted(p.stem for p in Path(f"raw/drift/{session}").glob("*.bag")))
    if not stems:
        raise WorkflowError(f"drift_session '{session}': no .bag files in raw/drift/{session}/")
    return stems


def session_files(scene, session, simulated):
    """Every file of a recording session, which provenance.json hashes whole: a real session's
    files as they are on disk (a note or a spare file beside the recordings too), a simulated
    one's as its simulate job declares them (``simulated``)."""
    if is_simulated(session):
        return list(simulated)
    return sorted(str(p) for p in Path(f"raw/{scene}/{session}").rglob("*") if p.is_file())


def volume_raw_inputs():
    """Every raw file of the volume sessions (provenance.json hashes them)."""
    return [f for s in P["volume_sessions"] for f in session_files(
        "volume", s, [f"raw/volume/{s}/{stem}.bag" for stem in volume_bag_stems(s)] + [f"raw/volume/{s}/lifts.csv"])]


def drift_shards():
    return [f"{DRIFT}/shards/{DRIFT_SESSION}/{name}.parquet" for name in drift_bag_stems(DRIFT_SESSION)]


VOLUME_TARGETS = [
    f"{VOLUME}/metrics.json",
    f"{VOLUME}/provenance.json",
    f"{VOLUME}/runtime.json",
    f"{VOLUME}/tables/table1_r2.md",
    f"{VOLUME}/tables/table2_volumes.md",
    f"{VOLUME}/tables/unseen_volumes.md",
    f"{VOLUME}/tables/runtime.md",
    f"{VOLUME}/tables/grid_search.md",
    f"{VOLUME}/figures/r2_by_modality.png",
    f"{VOLUME}/figures/mu_r2_curve.png",
    f"{VOLUME}/figures/true_vs_estimated.png",
    f"{VOLUME}/figures/error_vs_runtime.png",
    f"{VOLUME}/figures/pillar_map.png",
]
DRIFT_TARGETS = [f"{DRIFT}/metrics.json", f"{DRIFT}/provenance.json", f"{DRIFT}/fits.md",
                 f"{DRIFT}/figures/drift_curves.png"]


def provenance_stages(scene, simulator="if simulated"):
    """The stages that make a scene's numbers (the simulator's too when a session is
    simulated, or with simulator="always") and the scene's raw session folders."""
    stages_of = {"volume": ["papillarray-ingest", "volume-dataset", "volume-split", "volume-train", "volume-gridsearch",
                            "volume-baseline", "volume-report"],
                 "drift": ["papillarray-ingest", "drift-report"],
                 "tool": ["tool-ingest", "tool-dataset", "tool-split", "tool-train", "tool-model-report"]}
    kind = scene if scene in ("volume", "drift") else "tool"
    sessions = [DRIFT_SESSION] if kind == "drift" else P[f"{kind}_sessions"]
    simulator_of = {"volume": "volume-simulate", "drift": "drift-simulate", "tool": "tool-simulate"}
    simulated = simulator == "always" or any(is_simulated(s) for s in sessions)
    stages = ([simulator_of[kind]] if simulated else []) + stages_of[kind]
    return stages, [f"raw/{kind}/{s}" for s in sessions]


def provenance_args(scene):
    """`--provenance-stages ... --sessions ...`: provenance.json records their code, parameters
    and content."""
    stages, dirs = provenance_stages(scene)
    return "--provenance-stages " + " ".join(stages) + " --sessions " + " ".join(shlex.quote(d) for d in dirs)


def provenance_inputs(scene):
    """The code and parameter stamps of every stage provenance.json can describe: inputs of the
    report, so the record is rewritten whenever what it records changes. The simulator's are
    inputs whether or not a session is simulated, so that the graph (and dvc.yaml) does not
    change with the kind of session named in params.yaml."""
    stages, _ = provenance_stages(scene, simulator="always")
    # the training stage has a stamp per run (run_stamp_file), not one of its own
    runs = tool_runs(scene) if "tool-train" in stages else []
    return sorted({f for s in stages for f in stage_code(s)}) + [stamp_file(s) for s in stages if s != "tool-train"] + \
        [run_stamp_file(r) for r in runs]


@cache
def tool_trials(session):
    """(name, path, format) of a tool session's trials: planned by the simulator, or found on disk."""
    if is_simulated(session):
        return tuple((t.name, f"raw/tool/{session}/{t.name}", "native") for t in simulated_tool_plan())
    return tuple((name, str(path), fmt) for name, path, fmt in list_tool_trials(f"raw/tool/{session}"))


@cache
def simulated_tool_plan():
    return tuple(tool_plan(P))


def tool_trial_names(session):
    return [name for name, _, _ in tool_trials(session)]


def _tool_trial(session, trial):
    for name, path, fmt in tool_trials(session):
        if name == trial:
            return path, fmt
    raise WorkflowError(f"no trial {trial} in raw/tool/{session}")


def tool_trial_path(session, trial):
    return _tool_trial(session, trial)[0]


def tool_trial_format(session, trial):
    return _tool_trial(session, trial)[1]


def tool_trial_input(w):
    """The files a trial's ingest reads (so Snakemake re-ingests exactly the trials that change)."""
    path, fmt = _tool_trial(w.session, w.trial)
    if is_simulated(w.session):   # the simulator writes each trial folder whole; meta.json stands for it
        return [f"raw/tool/{w.session}/nano17.cal", f"{path}/meta.json"]
    return trial_files(path, fmt, f"raw/tool/{w.session}")


def tool_trial_files(session, trial):
    """The files of a trial as they are on the disk now (a simulated trial's, once written)."""
    path, fmt = _tool_trial(session, trial)
    return tuple(trial_files(path, fmt, f"raw/tool/{session}"))


def tool_trial_content(w):
    """The content stamp of every file of a trial (a simulated trial's too) and its session facts."""
    return content_stamp("tool", w.session, w.trial, tool_trial_files(w.session, w.trial),
                         f"{RESULTS}/tool/shards/{w.session}/{w.trial}.parquet", (w.session, w.trial))


@cache
def _tool_trial_meta(session, name):
    """(kind, tool) of a trial, from the simulator's plan or the trial's own metadata."""
    if is_simulated(session):
        t = next(t for t in simulated_tool_plan() if t.name == name)
        return t.kind, t.tool
    path, fmt = _tool_trial(session, name)
    if fmt == "native":
        meta = json.loads((Path(path) / "meta.json").read_text())
        return meta["kind"], meta["tool"]
    if fmt == "public":
        meta = public_trial_meta(read_trials_csv(f"raw/tool/{session}"), Path(path))
        return ("normal" if "data_normal" in path else "shear"), meta["tool"]
    from tactilepipe.tool.formats.rosbag import read_sidecar_meta
    meta = read_sidecar_meta(path)
    return meta["kind"], meta["tool"]


def _tool_kind(session, name):
    return _tool_trial_meta(session, name)[0]


def tool_names(kind):
    """The tools of a target's trials (each is left out in turn by the leave-one-tool-out runs)."""
    return sorted({_tool_trial_meta(s, name)[1] for s in P["tool_sessions"] for name in tool_trial_names(s)
                   if _tool_kind(s, name) == kind})


def tool_shards(kind):
    return [f"{RESULTS}/tool/shards/{s}/{name}.parquet" for s in P["tool_sessions"]
            for name in tool_trial_names(s) if _tool_kind(s, name) == kind]


def tool_raw_inputs(kind):
    """Raw trials of this kind (the pressing-strip figure shows their colour frames)."""
    return [f for s in P["tool_sessions"] for name in tool_trial_names(s) if _tool_kind(s, name) == kind
            for f in tool_trial_input(type("W", (), {"session": s, "trial": name})())]


def tool_session_files():
    """Every file of the tool sessions (provenance.json hashes them)."""
    return [f for s in P["tool_sessions"] for f in session_files(
        "tool", s, [f for name in tool_trial_names(s) for f in tool_trial_input(type("W", (), {"session": s, "trial": name})())])]


def drift_raw_inputs():
    """Every raw file of the drift session (provenance.json hashes them)."""
    return session_files("drift", DRIFT_SESSION, [f"raw/drift/{DRIFT_SESSION}/{stem}.bag" for stem in
                                                  drift_bag_stems(DRIFT_SESSION)] + [f"raw/drift/{DRIFT_SESSION}/session.json"])


TOOL_DATA_FIGURES = ["force_histogram", "force_profiles", "rmse_vs_force", "pressing_strip"]
TOOL_MODEL_FIGURES = ["sorted_predictions", "over_time", "per_tool", "window_heatmap", "regression",
                      "error_vs_runtime", "intervals"] + (["loto"] if P["tool_train"]["loto"] else [])
TOOL_MODEL_TABLES = ["variants", "intervals", "differences", "paper_orderings", "per_tool", "per_window", "runtime"] + \
    (["loto"] if P["tool_train"]["loto"] else [])


def tool_clock_figures():
    """Each tool session's clock-sync QC figure (score against lag per trial, chosen lag marked)."""
    return [f"{RESULTS}/tool/qc/{s}_clock_sync.png" for s in P["tool_sessions"]]


def tool_split_names(scene):
    """Every split file of a tool scene: each repeat of the drawn splits, one per held-out tool, lopo."""
    kind = scene_label(scene)
    return [split_name(k, r) for k in ("frame", "trial") for r in range(P["tool_split"]["repeats"])] + \
        [f"loto_{t}" for t in tool_names(kind)] + ["lopo"]


def tool_data_targets(scene):
    """QC report, data figures and every split of a tool scene (no model)."""
    return [f"{RESULTS}/{scene}/qc.md"] + tool_clock_figures() + \
        [f"{RESULTS}/{scene}/figures/{fig}.png" for fig in TOOL_DATA_FIGURES] + \
        [f"{RESULTS}/{scene}/splits/{split}.json" for split in tool_split_names(scene)]


def tool_model_targets(scene):
    """Metrics, tables and figures of every trained model run of a tool scene."""
    return [f"{RESULTS}/{scene}/metrics.json", f"{RESULTS}/{scene}/provenance.json", f"{RESULTS}/{scene}/runtime.json"] + \
        [f"{RESULTS}/{scene}/tables/{t}.md" for t in TOOL_MODEL_TABLES] + \
        [f"{RESULTS}/{scene}/figures/{fig}.png" for fig in TOOL_MODEL_FIGURES]


def tool_targets(scene):
    return tool_data_targets(scene) + tool_model_targets(scene)


def scene_targets(scenes):
    targets = {"volume": VOLUME_TARGETS, "drift": DRIFT_TARGETS,
               "tool_normal": tool_targets("tool_normal"), "tool_shear": tool_targets("tool_shear")}
    missing = [s for s in scenes if s not in targets]
    if missing:
        raise WorkflowError(f"scenes {missing} are not built by this workflow yet (available: {sorted(targets)})")
    return [t for s in scenes for t in targets[s]]


# `snakemake --report report.html`: every figure, table and metrics file, each with a caption that
# names the parameters behind it (workflow/report/); the front page lists all parameters.
report: "../report/workflow.rst"


def reported(files, scene):
    """Outputs marked for the report, under the scene's category (`{scene}` for the tool rules).
    Provenance and run times are outputs too, but not report items."""
    group = scene if scene in ("volume", "drift") else "tool"
    out = []
    for f in files:
        p = Path(f)
        if p.name in ("provenance.json", "runtime.json"):
            out.append(f)
            continue
        if p.suffix == ".md" and p.name != "qc.md":
            # every Markdown result but the tool data QC page has an HTML twin (write_table, the drift
            # fits), which is the report item: the report shows HTML as a page, Markdown only as a download
            out.append(f)
            f, p = str(p.with_suffix(".html")), p.with_suffix(".html")
        kind = {".png": "figures", ".json": "metrics"}.get(p.suffix, "tables")
        # a tool table named like a figure has its own caption
        stem = f"{p.stem}_table" if group == "tool" and p.suffix == ".html" and p.stem in TOOL_MODEL_FIGURES else p.stem
        out.append(report(f, caption=f"../report/{group}/{stem}.rst", category=scene, subcategory=kind))
    return out
