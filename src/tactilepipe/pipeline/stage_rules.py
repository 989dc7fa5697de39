"""Workflow rules generated from the stages' declarations.

A stage whose inputs and outputs are fixed files of a build declares its rule with its command
(``rule=`` of ``@command``, cli/registry.py): the scene it belongs to, its inputs and its outputs,
each a path under the build's folder keyed by the stage's own ``--<key>`` argument. From that the
workflow (workflow/rules/stages.smk) makes its Snakemake rule: inputs, outputs, code and parameter
stamp, log and shell line; its outputs join the scene's targets (pipeline/scenes.py), so its
scene's DVC stage and `tactilepipe diff` take it in too, and its scene's provenance.json records
it. An output named under ``report`` (its key -> the label the report lists it by) is an item of
`snakemake --report`, with its caption in workflow/report/<study>/<file stem>.rst. Adding such a
stage is its module (function and declaration), its caption and its test; `make dvc.yaml`
regenerates the DVC stages.

Stages whose jobs come from sessions or runs (one per recording, per trained model), or that
read or write outside the build's folder, keep their rules in workflow/rules/, written by hand;
the comment above each says what the declaration cannot say for it ("# By hand: ...").
"""

from __future__ import annotations

import posixpath
import re
from dataclasses import dataclass

from tactilepipe.core.errors import TactilepipeError
from tactilepipe.pipeline import codedeps
from tactilepipe.studies import contracts

KEYS = {"scene", "inputs", "outputs", "local", "report"}
# each scene's study (a study's contract declares its scenes)
SCENE_STUDY = {name: c.STUDY for c in contracts().values() for name in c.SCENES}
FLAG = re.compile(r"[a-z][a-z0-9-]*")
# names a generated rule's inputs and outputs cannot take: the rule's own inputs, and the names
# Snakemake's named lists keep for themselves
RESERVED = {"stamp", "params", "code", "keys", "items", "get", "count", "update", "copy", "index", "size",
            "size_mb", "size_files", "size_files_mb", "size_files_gb", "size_tempfiles"}
# folders of a build the workflow writes itself (pipeline/layout.py)
OWN_FOLDERS = ("params", "logs")


@dataclass(frozen=True)
class StageRule:
    stage: str                          # the command, e.g. "volume-split"
    scene: str
    inputs: tuple[tuple[str, str], ...]     # (argument, path under the build's folder)
    outputs: tuple[tuple[str, str], ...]
    local: bool                         # runs where Snakemake runs (a second's work), never queued
    report: tuple[tuple[str, str], ...] = ()     # (output argument, its label in `snakemake --report`)

    @property
    def name(self) -> str:
        """The rule's name: the stage's, with underscores (volume-split -> volume_split)."""
        return self.stage.replace("-", "_")

    def file_args(self, root: str) -> str:
        """Each input and output as its ``--<key> <path>``, quoted for the shell."""
        import shlex
        return " ".join(f"--{k} {shlex.quote(f'{root}/{p}')}" for k, p in self.inputs + self.outputs)

    def named_inputs(self, root: str) -> dict[str, str]:
        return {_key(k): f"{root}/{p}" for k, p in self.inputs}

    def named_outputs(self, root: str) -> dict[str, str]:
        return {_key(k): f"{root}/{p}" for k, p in self.outputs}

    def report_items(self, root: str) -> dict[str, tuple[str, str, str, dict]]:
        """{output name: (path, caption, subcategory, labels)} of the outputs that are report items;
        the caption relative to the rule files (workflow/rules/), as Snakemake's report() takes it."""
        paths, items = dict(self.outputs), {}
        for key, label in self.report:
            path = posixpath.join(root, paths[key])
            stem, ext = posixpath.splitext(posixpath.basename(path))
            caption = f"../report/{SCENE_STUDY[self.scene]}/{stem}.rst"
            items[_key(key)] = (path, caption, "figures" if ext == ".png" else "tables", {"result": label})
        return items


def _key(flag: str) -> str:
    return flag.replace("-", "_")


def stage_rules(scenes=None) -> list[StageRule]:
    """Every declared stage rule (of the scenes ``scenes``, default all), checked."""
    out = []
    for stage in codedeps.declared_stage_names():
        decl = codedeps.stage_rule(stage)
        if decl is None:
            continue
        rule = _checked(stage, decl)
        if scenes is None or rule.scene in scenes:
            out.append(rule)
    return out


def declared_outputs(scenes, root: str) -> list[str]:
    """What the declaring stages of the scenes ``scenes`` write: targets of those scenes."""
    return [f"{root}/{path}" for rule in stage_rules(scenes) for _, path in rule.outputs]


def _checked(stage: str, decl) -> StageRule:
    where = f"stage {stage}: its rule= declaration"
    if not isinstance(decl, dict) or not {"scene", "inputs", "outputs"} <= set(decl) or set(decl) - KEYS:
        raise TactilepipeError(f"{where} must be a dict of scene, inputs, outputs (and local, report), got {decl!r}")
    if not isinstance(decl["scene"], str) or decl["scene"] not in SCENE_STUDY:
        raise TactilepipeError(f"{where}: scene '{decl['scene']}' is none of {', '.join(SCENE_STUDY)}")
    if not decl["outputs"]:
        raise TactilepipeError(f"{where}: a rule needs at least one output")
    flags = codedeps.stage_flags(stage)
    files = {}
    for part in ("inputs", "outputs"):
        if not isinstance(decl[part], dict):
            raise TactilepipeError(f"{where}: {part} must map an argument to a path")
        for key, path in decl[part].items():
            if not (isinstance(key, str) and FLAG.fullmatch(key)) or f"--{key}" not in flags:
                raise TactilepipeError(f"{where}: {part} key '{key}' is not one of the stage's arguments "
                                       f"({', '.join(sorted(flags))})")
            if _key(key) in RESERVED or key in files:
                raise TactilepipeError(f"{where}: argument '--{key}' is given twice, or its name is one the "
                                       f"rule keeps for itself ({', '.join(sorted(RESERVED))})")
            if not isinstance(path, str) or not path or "{" in path or "\\" in path or \
                    posixpath.normpath(path) != path or path.startswith(("/", "../")) or \
                    path.split("/")[0] in OWN_FOLDERS:
                raise TactilepipeError(f"{where}: {part}.{key}: '{path}' must be a fixed path under the build's "
                                       f"folder (results/<build>/), outside its {' and '.join(OWN_FOLDERS)} "
                                       f"folders, e.g. volume/summary.json")
            files[key] = path
    report = decl.get("report", {})
    if not isinstance(report, dict) or any(k not in decl["outputs"] or not isinstance(v, str) or not v.strip()
                                           for k, v in report.items()):
        raise TactilepipeError(f"{where}: report must map some of its outputs' arguments to the label the report "
                               f"lists each by, e.g. {{'out': 'Lifts per volume'}}, got {report!r}")
    return StageRule(stage, decl["scene"], tuple(decl["inputs"].items()), tuple(decl["outputs"].items()),
                     bool(decl.get("local", False)), tuple(report.items()))
