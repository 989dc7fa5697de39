"""The recording sessions a build reads, as one validated table: every recording (a PapillArray bag
of the volume or drift study, a trial of the tool study) with the files its ingest reads.

A real session's recordings are found on the disk (raw/<study>/<session>/: the bags lifts.csv
lists, the .bag files of a drift session, the trial folders or bags of a tool session); a
simulated session's (``sim-<scale>``) come from the simulator's plan, since they do not exist yet
when the workflow plans the run that writes them. The workflow asks the sheet for its jobs' names
and inputs; `tactilepipe sessions` prints it, so a lab sees what a build will read before it runs.
Each answer is computed once per sheet: nothing in a build writes into a real session's folder.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from tactilepipe.core.errors import ConfigError, InputError
from tactilepipe.core.simulated import is_simulated

STUDIES = ("volume", "drift", "tool")
# a recording's name is one component of its output paths (spaces are fine: rules quote paths)
PLAIN_NAME = re.compile(r"[^/\\\x00-\x1f.][^/\\\x00-\x1f]*")


@dataclass(frozen=True)
class Recording:
    study: str          # volume | drift | tool: the folder raw/<study>/
    session: str
    name: str           # the bag's stem or the trial's name: names its shard
    path: str           # the bag, or the trial's folder or bag
    format: str         # bag (PapillArray) | native | public | ros (tool trials)
    kind: str = ""      # a tool trial's force: normal | shear
    tool: str = ""      # a tool trial's tool


class SessionSheet:
    """The sessions ``params`` names (``volume_sessions``, ``drift_session``, ``tool_sessions``),
    their recordings and files, under ``raw`` (the project's raw/ folder)."""

    def __init__(self, params: dict, raw: str = "raw"):
        self.p, self.raw = params, raw
        self.recordings = cache(self.recordings)
        self._tool_plan = cache(self._tool_plan)

    def sessions(self, study: str) -> list[str]:
        return [self.p["drift_session"]] if study == "drift" else list(self.p[f"{study}_sessions"])

    def folder(self, study: str, session: str) -> str:
        return f"{self.raw}/{study}/{session}"

    def recordings(self, study: str, session: str) -> tuple[Recording, ...]:
        """The session's recordings, in the order the simulator plans or the disk sorts them."""
        found = {"volume": self._volume, "drift": self._drift, "tool": self._tool}[study](session)
        seen = set()
        for r in found:
            if not PLAIN_NAME.fullmatch(r.name):
                raise InputError(r.path, f"recording name {r.name!r} cannot name a file of its own (no slash, "
                                         f"backslash or control character, no leading dot)")
            if r.name in seen:
                raise InputError(self.folder(study, session), f"two recordings are named '{r.name}': each names "
                                                              f"its own shard")
            seen.add(r.name)
        return found

    def recording(self, study: str, session: str, name: str) -> Recording:
        for r in self.recordings(study, session):
            if r.name == name:
                return r
        raise ConfigError(f"no recording '{name}' in {self.folder(study, session)}")

    def bag(self, study: str, session: str, stem: str) -> Recording:
        """The PapillArray bag ``stem`` of a session, whether or not its session lists it."""
        return Recording(study, session, stem, f"{self.folder(study, session)}/{stem}.bag", "bag")

    # --- what each recording's ingest reads ------------------------------------------------------
    def ingest_inputs(self, r: Recording) -> list[str]:
        """The files the ingest job of ``r`` declares: a simulated trial's meta.json stands for its
        folder (the simulator writes it whole), a real one's files are those reading it opens."""
        if r.study != "tool":
            return [r.path]
        if is_simulated(r.session):
            return [f"{self.folder('tool', r.session)}/nano17.cal", f"{r.path}/meta.json"]
        return self.files_on_disk(r)

    def files_on_disk(self, r: Recording) -> list[str]:
        """Every file reading ``r`` opens, as the disk holds them now (a simulated trial's, once
        written): what its content stamp hashes."""
        if r.study != "tool":
            return [r.path]
        from tactilepipe.tool.formats.trials import trial_files
        return trial_files(r.path, r.format, self.folder("tool", r.session))

    def session_files(self, study: str, session: str) -> list[str]:
        """Every file of a session, which provenance.json hashes whole: a real session's files as
        they are on the disk (a note or a spare file too), a simulated one's as its simulator
        declares them."""
        folder = self.folder(study, session)
        if not is_simulated(session):
            return sorted(str(p) for p in Path(folder).rglob("*") if p.is_file())
        recordings = self.recordings(study, session)
        if study == "tool":
            return [f for r in recordings for f in self.ingest_inputs(r)]
        facts = {"volume": "lifts.csv", "drift": "session.json"}[study]
        return [r.path for r in recordings] + [f"{folder}/{facts}"]

    def study_files(self, study: str) -> list[str]:
        """Every file of every session of ``study``."""
        return [f for s in self.sessions(study) for f in self.session_files(study, s)]

    # --- the tool study's trials by kind ---------------------------------------------------------
    def trials(self, kind: str) -> list[Recording]:
        """The tool trials of one force kind, over every tool session."""
        return [r for s in self.sessions("tool") for r in self.recordings("tool", s) if r.kind == kind]

    def trial_inputs(self, kind: str) -> list[str]:
        """The files the ingest jobs of one kind's trials read."""
        return [f for r in self.trials(kind) for f in self.ingest_inputs(r)]

    def tools(self, kind: str) -> list[str]:
        """The tools of a kind's trials (the leave-one-tool-out runs leave each out in turn)."""
        return sorted({r.tool for r in self.trials(kind)})

    def check(self) -> None:
        """Read every session params.yaml names (their recordings, each tool trial's metadata): a
        wrong one raises, naming the file."""
        for _ in self.rows():
            pass

    def rows(self):
        """One row per recording of the build: study, session, name, format, kind, tool, path."""
        for study in STUDIES:
            for s in self.sessions(study):
                for r in self.recordings(study, s):
                    yield r

    # --- finding them ----------------------------------------------------------------------------
    def _volume(self, session: str) -> tuple[Recording, ...]:
        folder = self.folder("volume", session)
        if is_simulated(session):
            from tactilepipe.volume.simulate import session_plan
            stems = [lift.name for lift in session_plan(self.p["simulate_volume"])]
        else:
            from tactilepipe.volume.labels import read_session_labels
            stems = [Path(row["bag"]).stem for row in read_session_labels(folder)]
        return tuple(self.bag("volume", session, s) for s in stems)

    def _drift(self, session: str) -> tuple[Recording, ...]:
        folder = self.folder("drift", session)
        if is_simulated(session):
            from tactilepipe.drift.simulate import session_plan
            stems = session_plan(self.p)
        else:
            if not Path(folder).is_dir():
                raise InputError(folder, "session folder not found (params.yaml drift_session)")
            stems = sorted(p.stem for p in Path(folder).glob("*.bag"))
            if not stems:
                raise InputError(folder, "no .bag files: the drift session's recordings are its bags")
        return tuple(self.bag("drift", session, s) for s in stems)

    def _tool_plan(self):
        from tactilepipe.tool.sim import session_plan
        return tuple(session_plan(self.p))

    def _tool(self, session: str) -> tuple[Recording, ...]:
        folder = self.folder("tool", session)
        if is_simulated(session):
            return tuple(Recording("tool", session, t.name, f"{folder}/{t.name}", "native", t.kind, t.tool)
                         for t in self._tool_plan())
        from tactilepipe.tool.formats.trials import list_trials
        out = []
        for name, path, fmt in list_trials(folder):
            kind, tool = _trial_kind_and_tool(folder, Path(path), fmt)
            out.append(Recording("tool", session, name, str(path), fmt, kind, str(tool)))
        return tuple(out)


def _trial_kind_and_tool(session_dir: str, path: Path, fmt: str) -> tuple[str, str]:
    """(kind, tool) of a recorded trial, from its own metadata (native meta.json, a ROS bag's
    sidecar) or, in the public layout, its kind folder and the session's trials.csv."""
    if fmt == "native":
        from tactilepipe.tool.formats.native_layout import TrialMeta
        meta = TrialMeta.read(path)
        return meta.kind, meta.tool
    if fmt == "public":
        from tactilepipe.tool.formats.trials import public_trial_meta, read_trials_csv
        meta = public_trial_meta(read_trials_csv(session_dir), path)
        return ("normal" if "data_normal" in str(path) else "shear"), meta["tool"]
    from tactilepipe.tool.formats.rosbag import read_sidecar_meta
    meta = read_sidecar_meta(path)
    return meta["kind"], meta["tool"]
