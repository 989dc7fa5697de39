"""A build's provenance as a Workflow Run RO-Crate, for readers who do not run this project.

``provenance.json`` is the project's own record, read by `tactilepipe diff`; the crate says the
same in a vocabulary other tools read (the Process Run Crate, Workflow Run Crate and Workflow
RO-Crate profiles, written with ro-crate-py). The main entity is the workflow: the Snakefile, at
its commit, with each stage's code (by its sha256) and the packages. Its runs are CreateActions,
one per scene and one for the whole build, each naming its inputs (``object``: the recording
sessions, each by DVC's hash, and the parameter values each stage was given; the build's also the
parameter stamps), its outputs (``result``), its machine (``location``), the environment variables
that chose the numerical kernels (``environment``) and when it ran: the first start and last end
of the Snakemake jobs that wrote its outputs, from Snakemake's own record (none where `dvc repro`
made the build, or the results were pulled). Sessions are not copied: DVC keeps them, and a
session's ``identifier`` (its md5, ``<md5>.dir`` for a folder) names its object in the project's
DVC cache and remote. The scenes' records, tables and figures and the stamps are copied in.
"""

from __future__ import annotations

import base64
import hashlib
import json
import re
from datetime import datetime, timezone
from pathlib import Path

from tactilepipe.core.errors import InputError
from tactilepipe.core.metric_rows import FOLDER as METRICS_FOLDER
from tactilepipe.pipeline.layout import results_root

PROFILES = {"https://w3id.org/ro/wfrun/process/0.5": "Process Run Crate",
            "https://w3id.org/ro/wfrun/workflow/0.5": "Workflow Run Crate",
            "https://w3id.org/workflowhub/workflow-ro-crate/1.0": "Workflow RO-Crate"}
RUN_TERMS = "https://w3id.org/ro/terms/workflow-run/context"
WORKFLOW = "Snakefile"
SCENE_RECORDS = ("scores.json", "provenance.json", "runtime.json", "metrics.json")   # metrics.json: older builds
SCENE_FOLDERS = (METRICS_FOLDER, "tables", "figures")
ENGINES = ("snakemake", "dvc")          # listed first among the packages
DVC_HASH = re.compile(r"[0-9a-f]{32}(\.dir)?")     # a file's md5, a folder's manifest md5


def scene_provenances(project: Path, build: str) -> dict[str, dict]:
    """Every scene of the build that has a provenance.json, by name."""
    results = project / results_root(build)
    found = {}
    for path in sorted(results.glob("*/provenance.json")):
        try:
            found[path.parent.name] = json.loads(path.read_text())
        except ValueError as exc:
            raise InputError(path, f"not JSON ({exc})") from None
    if not found:
        raise InputError(results, "no scene has a provenance.json: build it first (make run, make smoke)")
    return found


def snakemake_times(project: Path) -> dict[str, tuple[float, float]]:
    """(start, end) of the job that made each file, by its path, from Snakemake's own record
    (.snakemake/metadata/: one JSON per output, named by the url-safe base64 of its path, cut in
    parts no longer than a file name, all but the last marked by a leading '@'). Empty where
    Snakemake did not make the build (`dvc repro`, a clone with pulled results)."""
    root = project / ".snakemake" / "metadata"
    times = {}
    for record in (p for p in root.rglob("*") if p.is_file()) if root.is_dir() else ():
        try:
            path = base64.urlsafe_b64decode("".join(part.lstrip("@") for part in record.relative_to(root).parts))
            entry = json.loads(record.read_text())
            times[path.decode()] = (float(entry["starttime"]), float(entry["endtime"]))
        except (ValueError, KeyError, TypeError, OSError):   # a record being written, or of an older format
            continue
    return times


def span(times: dict[str, tuple[float, float]], paths: list[str]) -> tuple[str, str] | None:
    """ISO 8601 start and end of the jobs that made ``paths`` (a folder: the files under it)."""
    made = [t for path, t in times.items() for p in paths if path == p or path.startswith(p.rstrip("/") + "/")]
    if not made:
        return None
    iso = [datetime.fromtimestamp(x, timezone.utc).isoformat() for x in (min(s for s, _ in made), max(e for _, e in made))]
    return iso[0], iso[1]


def flat(params: dict, prefix: str = "") -> dict[str, object]:
    """Dotted keys of nested parameter values; a list is one value (JSON)."""
    out = {}
    for key, value in params.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, dict):
            out.update(flat(value, name))
        else:
            out[name] = value if isinstance(value, (str, int, float, bool)) else json.dumps(value)
    return out


class CrateWriter:
    """The crate of one build: the workflow, a CreateAction per scene, one for the whole build."""

    def __init__(self, project: Path, build: str, times: dict[str, tuple[float, float]], agent: str | None,
                 engine_version: str | None):
        from rocrate.rocrate import ROCrate
        self.project, self.build, self.times = project, build, times
        self.results = results_root(build)
        # RO-Crate 1.1, which the run profiles of 0.5 are written against, and the terms they add
        # (``environment``)
        self.crate = ROCrate(version="1.1")
        self.crate.metadata.extra_contexts.append(RUN_TERMS)
        self.inputs, self.outputs, self.params, self.code, self.packages = {}, {}, {}, {}, {}
        self.scenes = []                                   # (scene, its action, its provenance)
        self.agent = self._person(agent or _git_user(project))
        # the main workflow: the Snakefile, in Snakemake's language (the version that ran it)
        self.workflow = self.crate.add_workflow(project / WORKFLOW, dest_path=WORKFLOW, main=True, lang="snakemake",
                                                lang_version=engine_version)
        self.workflow["name"] = "tactilepipe"

    # --- entities the actions share ----------------------------------------------------------
    def _context(self, ident: str, properties: dict):
        from rocrate.model.contextentity import ContextEntity
        return self.crate.get(ident) or self.crate.add(ContextEntity(self.crate, ident, properties=properties))

    def _person(self, who: str | None):
        if not who:
            return None
        ident = who if who.startswith(("http://", "https://")) else f"#agent-{_fragment(who)}"
        return self._context(ident, {"@type": "Person", "name": who})

    def _md5(self, value: str):
        """DVC's md5 as an identifier: the object ``files/md5/<2 digits>/<rest>`` of a DVC cache or remote."""
        return self._context(f"#md5-{value}", {
            "@type": "PropertyValue", "propertyID": "DVC md5", "name": "DVC md5", "value": value,
            "description": f"DVC's hash: the object files/md5/{value[:2]}/{value[2:]} of a DVC cache or remote"})

    def _session(self, path: str, recorded: str):
        """A recording session, not copied (DVC keeps it): named by its path, found by its md5. A
        build recorded before provenance.json took DVC's hash has a sha256 of its own there."""
        if path not in self.inputs:
            dvc = DVC_HASH.fullmatch(recorded)
            folder = recorded.endswith(".dir") if dvc else not (self.project / path).is_file()
            kind = "Dataset" if folder else "File"
            ident = self._md5(recorded) if dvc else self._context(f"#sha256-{recorded}", {
                "@type": "PropertyValue", "propertyID": "tactilepipe session sha256", "value": recorded,
                "description": "sha256 over the session's relative file names and their sha256 (no DVC object)"})
            self.inputs[path] = self._context(f"#{_fragment(path.rstrip('/'))}{'/' if folder else ''}", {
                "@type": kind, "name": path, "alternateName": path, "identifier": ident,
                "description": "a recording session, kept by DVC (not copied into this crate)"})
        return self.inputs[path]

    def _output(self, rel: str):
        from tactilepipe.pipeline.provenance import dvc_hash
        if rel not in self.outputs:
            self.outputs[rel] = self.crate.add_file(self.project / rel, dest_path=rel,
                                                    properties={"identifier": self._md5(dvc_hash(self.project / rel))})
        return self.outputs[rel]

    def _param(self, scene: str, stage: str, key: str, value):
        ident = f"#param-{_fragment(stage)}-{_fragment(key)}"
        if ident in self.params and self.params[ident]["value"] != value:
            ident = f"#param-{_fragment(scene)}-{_fragment(stage)}-{_fragment(key)}"        # one stage given other values in another scene
        if ident not in self.params:
            self.params[ident] = self._context(ident, {"@type": "PropertyValue", "name": f"{stage}: {key}",
                                                       "value": value})
        return self.params[ident]

    def _stage(self, stage: str, code_sha256: str | None):
        ident = f"#stage-{stage}-{code_sha256}"
        if ident not in self.code:
            self.code[ident] = self._context(ident, {
                "@type": "SoftwareSourceCode", "name": f"tactilepipe {stage}", "identifier": code_sha256,
                "description": "a stage's code, identified by the sha256 over the source files it runs"})
        return self.code[ident]

    def _software(self, name: str, version: str | None) -> None:
        ident = f"#software-{name}-{version}"
        if version and ident not in self.packages:
            self.packages[ident] = self._context(ident, {"@type": "SoftwareApplication", "name": name,
                                                         "softwareVersion": version})

    def _machine(self, env: dict):
        cpu = env.get("cpu") or {}
        props = {"machine": env.get("machine"), "cpu": cpu.get("model"), "cpu vendor": cpu.get("vendor"),
                 "cpu family": cpu.get("family"), "cpu model number": cpu.get("model_number"),
                 "vector extensions": " ".join(cpu.get("vector_extensions") or []), "python": env.get("python")}
        ident = f"#machine-{_digest(json.dumps(props, sort_keys=True))}"
        parts = [self._context(f"{ident}-{_fragment(k)}", {"@type": "PropertyValue", "name": k, "value": v})
                 for k, v in props.items() if v]
        return self._context(ident, {
            "@type": "Place", "name": f"{props['machine']} machine, {props['cpu']}", "additionalProperty": parts,
            "description": "the machine the scene was made on: its CPU decides the numerical kernels"})

    def _environment(self, env: dict) -> list:
        return [self._context(f"#env-{_fragment(k)}-{_digest(v)}", {"@type": "PropertyValue", "name": k, "value": v})
                for k, v in sorted((env.get("kernel_settings") or {}).items()) if v is not None]

    # --- the actions -------------------------------------------------------------------------
    def _action(self, ident: str, name: str, description: str, inputs: list, outputs: list, made: list[str],
                where: list, env: list):
        """A CreateAction of the workflow; its times those of the Snakemake jobs that wrote ``made``."""
        props = {"name": name, "description": description, "location": where, "environment": env,
                 "actionStatus": {"@id": "http://schema.org/CompletedActionStatus"}}
        when = span(self.times, made)
        if when:
            props["startTime"], props["endTime"] = when
        if self.agent is not None:
            props["agent"] = self.agent
        return self.crate.add_action(self.workflow, identifier=ident, object=inputs, result=outputs,
                                     properties=props)

    def add_scene(self, scene: str, prov: dict) -> None:
        """The scene's part of the build: its sessions and the parameter values of its stages
        in, its records, tables and figures out, on its machine, at its commit."""
        env, git, stages = prov.get("environment") or {}, prov.get("git") or {}, prov.get("stages") or {}
        folder = self.project / self.results / scene
        files = [f"{self.results}/{scene}/{n}" for n in SCENE_RECORDS if (folder / n).is_file()]
        files += sorted(p.relative_to(self.project).as_posix() for d in SCENE_FOLDERS
                        for p in (folder / d).rglob("*") if p.is_file())
        sessions = [self._session(path, md5) for path, md5 in sorted((prov.get("sessions") or {}).items())]
        params = [self._param(scene, stage, k, v) for stage, given in sorted(stages.items())
                  for k, v in flat(given.get("params") or {}).items()]
        for stage, given in sorted(stages.items()):
            self._stage(stage, given.get("code_sha256"))
        packages = env.get("packages") or {}
        for name in [n for n in ENGINES if n in packages] + sorted(set(packages) - set(ENGINES)):
            self._software(name, packages[name])
        self._software("python", env.get("python"))
        dirty = " with uncommitted changes" if git.get("uncommitted_changes") else ""
        action = self._action(f"#scene-{scene}", f"tactilepipe build {self.build}: scene {scene}",
                              f"the stages {', '.join(sorted(stages))} at commit {git.get('commit')}{dirty}",
                              sessions + params, [self._output(f) for f in files],
                              [f"{self.results}/{scene}/", *(prov.get("sessions") or {})],
                              [self._machine(env)], self._environment(env))
        self.scenes.append((scene, action, prov))

    def finish(self):
        """The build's CreateAction over every scene; the workflow's commit, stage code and packages;
        the profiles."""
        commits = sorted({(p.get("git") or {}).get("commit") or "unknown" for *_, p in self.scenes})
        self.workflow["version"] = ", ".join(commits)
        self.workflow["hasPart"] = list(self.code.values())
        self.workflow["softwareRequirements"] = list(self.packages.values())
        stamps = [self.crate.add_file(p, dest_path=p.relative_to(self.project).as_posix(), properties={
            "description": "the parameter values a stage was given (the workflow's stamp)"})
            for p in sorted((self.project / self.results / "params").rglob("*.json"))]
        scenes = [s for s, *_ in self.scenes]
        machines = {m.id: m for _, a, _ in self.scenes for m in a["location"]}
        env = {e.id: e for _, a, _ in self.scenes for e in a.get("environment") or []}
        build = self._action(f"#build-{self.build}", f"tactilepipe build {self.build}",
                             f"every scene of {self.results}/ ({', '.join(scenes)}) at commit {', '.join(commits)}",
                             list(self.inputs.values()) + stamps + list(self.params.values()),
                             list(self.outputs.values()), [f"{self.results}/", *(p for p in self.inputs)],
                             list(machines.values()), list(env.values()))
        for ident, name in PROFILES.items():
            self._context(ident, {"@type": "CreativeWork", "name": name, "version": ident.rsplit("/", 1)[-1]})
        root = self.crate.root_dataset
        root["conformsTo"] = [{"@id": i} for i in PROFILES]
        root["name"], root["description"] = f"tactilepipe build {self.build}", build["description"]
        root["mentions"] = [build] + [a for _, a, _ in self.scenes]
        return self.crate


def _fragment(text: str) -> str:
    """``text`` as part of an entity's identifier (an IRI: no spaces, no quotes)."""
    from urllib.parse import quote
    return quote(str(text), safe="/-._~")


def _digest(text: str) -> str:
    return hashlib.sha256(str(text).encode()).hexdigest()[:12]


def _git_user(project: Path) -> str | None:
    import subprocess
    try:
        proc = subprocess.run(["git", "config", "user.name"], cwd=project, capture_output=True, text=True)
    except OSError:
        return None
    return proc.stdout.strip() or None


def write_crate(project: Path, build: str, out: Path, agent: str | None = None):
    """Write the crate of ``build`` (results/<build>/ of ``project``) into the folder ``out``."""
    provenances = scene_provenances(project, build)
    engines = [((p.get("environment") or {}).get("packages") or {}).get("snakemake") for p in provenances.values()]
    writer = CrateWriter(project, build, snakemake_times(project), agent, next((v for v in engines if v), None))
    for scene, prov in provenances.items():
        writer.add_scene(scene, prov)
    crate = writer.finish()
    out.mkdir(parents=True, exist_ok=True)
    crate.write(out)
    return crate
