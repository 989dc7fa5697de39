"""The workflow's stamps on the disk: which file holds each, when it is rewritten, and what a dry
run does instead. The stamps' contents are made in pipeline/stamps.py (parameters) and
pipeline/manifest.py (raw file content); this keeps the files.

- A stage's parameter stamp, results/<build>/params/<stage>.json (a simulator's under its scale,
  results/<scale>/params/, so a second build of one scale re-simulates nothing), and a training
  job's, results/<build>/params/<its stage>/<run>.json (tool-train/): rewritten only when their values change. A
  change then re-runs the job by file time, also where Snakemake has no record of earlier runs
  (a fresh clone, a new machine).
- An ingest job's content stamp, .tactilepipe/content/<study>/<session>/<recording>.json: the
  hashes of its raw files, rewritten when one changes, so an edit that kept its old time
  (cp -p, rsync -t) re-runs the job. Local state, not versioned.

A dry run must not rewrite a tracked file: a changed stamp is written to a scratch folder outside
the project instead, whose newer time plans the same re-run. Whether this is a dry run is known
only once the graph is being built, so ``dry_run`` is asked each time.
"""

from __future__ import annotations

import atexit
import shutil
import sys
import tempfile
from functools import cache
from pathlib import Path
from typing import Callable

from tactilepipe.core.study import Recording
from tactilepipe.pipeline import codedeps, layout, manifest, stamps
from tactilepipe.pipeline.sessions import SessionSheet
from tactilepipe.studies import contracts

CONTRACTS = contracts()
SCALE_STAGES = {c.SIMULATOR for c in CONTRACTS.values()}
CONTENT_STAMPS = ".tactilepipe/content"


class StampKeeper:
    """Keeps the stamps of one workflow run. ``dry_run()`` says whether it is a dry run;
    ``written(path)`` is told of every stamp file written after the run started."""

    def __init__(self, params: dict, sheet: SessionSheet, dry_run: Callable[[], bool],
                 written: Callable[[str], None]):
        self.p, self.sheet, self.dry_run, self.written = params, sheet, dry_run, written
        self.params_dir = Path(layout.results_root(params["build"])) / "params"
        self.scale_params_dir = Path(layout.results_root(params["scale"])) / "params"
        self.stage = cache(self.stage)
        self.run = cache(self.run)
        self.content = cache(self.content)
        self._manifest = cache(self._manifest)
        self._absent = []            # content stamps of files a run had yet to make

    def stage(self, stage: str) -> str:
        """The parameter stamp of ``stage``: its declared keys and graph keys (cli @command)."""
        text = stamps.stamp_text(stage, codedeps.stage_param_keys(stage), codedeps.stage_graph_keys(stage), self.p)
        folder = self.scale_params_dir if stage in SCALE_STAGES else self.params_dir
        return self._current(folder, f"{stage}.json", text)

    def scale_stamps(self, stages) -> list[str]:
        """The stamps of those of ``stages`` kept in the scale's folder rather than the build's."""
        return [self.stage(s) for s in stages if s in SCALE_STAGES]

    def run(self, study: str, run: str) -> str:
        """A training job's own stamp: its stage's keys and the run's definition (the study's
        contract: RUN_STAGE, run_definition, run_source_keys), so a key only some runs read, or a
        new variant, re-runs only those."""
        c = CONTRACTS[study]
        text = stamps.run_stamp_text(c.run_definition(self.p, run), codedeps.stage_param_keys(c.RUN_STAGE),
                                     codedeps.stage_graph_keys(c.RUN_STAGE), c.run_source_keys(self.p, run), self.p)
        return self._current(self.params_dir, f"{c.RUN_STAGE}/{run}.json", text)

    def content(self, recording: Recording, output: str) -> str:
        """The content stamp of every file reading ``recording`` opens, for the job writing ``output``."""
        r = recording
        name = f"{r.study}/{r.session}/{r.name}.json"
        scratch = Path(self._scratch()) / "changed-content" / name if self.dry_run() else None
        stamp, found = f"{CONTENT_STAMPS}/{name}", self._manifest(self.sheet.folder(r.study, r.session))
        path, change = manifest.update_stamp(stamp, found, self.sheet.files_on_disk(r), output, dry_run_copy=scratch)
        if change:
            print(f"{stamp}: {change}", file=sys.stderr, flush=True)
        if not self.dry_run() and manifest.holds_absent(path):
            self._absent.append((stamp, found, r, output))
        self.written(str(path))
        return str(path)

    def record_made_files(self) -> None:
        """After a successful run: stamp the files that did not exist when it planned its jobs (a
        session it simulated), so the first edit after this run is a change."""
        for stamp, found, recording, output in self._absent:
            manifest.update_stamp(stamp, found, self.sheet.files_on_disk(recording), output)

    def _current(self, folder: Path, name: str, text: str) -> str:
        """folder/name holding ``text``: left alone when it already does, else rewritten, or in a
        dry run written to the scratch folder instead (its path returned)."""
        path = folder / name
        old = path.read_text() if path.is_file() else None
        if old == text:
            return str(path)
        print(f"{path}: {stamps.stamp_change(old, text)}", file=sys.stderr, flush=True)
        if self.dry_run():
            path = Path(self._scratch()) / "changed-params" / name
            path.parent.mkdir(parents=True, exist_ok=True)
        from tactilepipe.core.atomic import write_text
        write_text(path, text)
        self.written(str(path))
        return str(path)

    def _manifest(self, folder: str) -> manifest.SessionManifest:
        found = manifest.SessionManifest(folder)
        atexit.register(found.save)          # the hash cache is written once, as the run exits
        return found

    @staticmethod
    @cache
    def _scratch() -> str:
        folder = tempfile.mkdtemp(prefix="tactilepipe-dry-run-")
        atexit.register(shutil.rmtree, folder, ignore_errors=True)
        return folder
