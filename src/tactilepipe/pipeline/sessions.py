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
from functools import cache
from pathlib import Path

from tactilepipe.core.errors import ConfigError, InputError
from tactilepipe.core.simulated import is_simulated
from tactilepipe.core.study import Recording
from tactilepipe.studies import contracts

CONTRACTS = contracts()
STUDIES = tuple(CONTRACTS)
# a recording's name is one component of its output paths (spaces are fine: rules quote paths)
PLAIN_NAME = re.compile(r"[^/\\\x00-\x1f.][^/\\\x00-\x1f]*")


class SessionSheet:
    """The sessions ``params`` names (each study's, core/study.py: ``volume_sessions``,
    ``drift_session``, ``tool_sessions``), their recordings and files, under ``raw`` (the
    project's raw/ folder). Each study's own reader finds them (its contract.py)."""

    def __init__(self, params: dict, raw: str = "raw"):
        self.p, self.raw = params, raw
        self.recordings = cache(self.recordings)

    def sessions(self, study: str) -> list[str]:
        return CONTRACTS[study].sessions(self.p)

    def folder(self, study: str, session: str) -> str:
        return f"{self.raw}/{study}/{session}"

    def recordings(self, study: str, session: str) -> tuple[Recording, ...]:
        """The session's recordings, in the order the simulator plans or the disk sorts them."""
        found = CONTRACTS[study].recordings(self.p, self.folder(study, session), session)
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
        """The files the ingest job of ``r`` declares (its study says which: a simulated trial's
        meta.json stands for its folder, which the simulator writes whole)."""
        return CONTRACTS[r.study].ingest_inputs(r, self.folder(r.study, r.session))

    def files_on_disk(self, r: Recording) -> list[str]:
        """Every file reading ``r`` opens, as the disk holds them now (a simulated trial's, once
        written): what its content stamp hashes."""
        return CONTRACTS[r.study].files_on_disk(r, self.folder(r.study, r.session))

    def session_files(self, study: str, session: str) -> list[str]:
        """Every file of a session, which provenance.json hashes whole: a real session's files as
        they are on the disk (a note or a spare file too), a simulated one's as its simulator
        declares them."""
        folder = self.folder(study, session)
        if not is_simulated(session):
            return sorted(str(p) for p in Path(folder).rglob("*") if p.is_file())
        return CONTRACTS[study].simulated_files(self.recordings(study, session), folder)

    def study_files(self, study: str) -> list[str]:
        """Every file of every session of ``study``."""
        return [f for s in self.sessions(study) for f in self.session_files(study, s)]

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
