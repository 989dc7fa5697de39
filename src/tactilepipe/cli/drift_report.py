"""Stage of the drift study: its drift curves, fits and figures. Its cross-key checks are its sensor's
(the workflow runs every study's: tactilepipe/studies.py)."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.papillarray.checks import check as papillarray_check


@command("drift-report", "scores.json, metrics/, fits and figures of the drift study",
         checks=(papillarray_check,),
         params=("drift",), graph=("drift_session",),
         args=(arg("--in-dir", required=True, help="the scene's results folder"),
               arg("--shards", nargs="+", required=True, help="the recordings' shards"),
               arg("--session-meta", required=True, help="the session's session.json (reference weight)")),
         provenance=True)
def cmd_drift_report(args, p) -> None:
    from tactilepipe.drift.analyse import run
    run([Path(s) for s in args.shards], Path(args.session_meta), Path(args.in_dir), p)
    from tactilepipe.cli.provenance import write_scene_provenance
    write_scene_provenance(args, Path(args.in_dir))
