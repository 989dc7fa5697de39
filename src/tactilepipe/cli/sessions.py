"""`tactilepipe sessions`: the recordings a build will read, as the workflow sees them."""

from __future__ import annotations

import sys

from tactilepipe.cli.registry import arg, command
from tactilepipe import studies

COLUMNS = ("study", "session", "name", "format", "kind", "tool", "path")


@command("sessions", "list every recording of the sessions params.yaml names (a simulated session's as planned), "
                     "checked as the workflow checks them: one tab-separated row each",
         params=("volume_sessions", "drift_session", "tool_sessions", "simulate_volume", "simulate_drift",
                 "simulate_tool"),
         checks=studies.CHECKS,             # the whole file, as the workflow checks it
         args=(arg("--study", choices=["volume", "drift", "tool"], help="only this study's sessions"),))
def cmd_sessions(args, p) -> None:
    from tactilepipe.pipeline.sessions import SessionSheet
    sheet = SessionSheet(p)
    rows = [r for r in sheet.rows() if args.study in (None, r.study)]
    print("\t".join(COLUMNS))
    for r in rows:
        print("\t".join(str(getattr(r, c)) for c in COLUMNS))
    print(f"{len(rows)} recordings", file=sys.stderr)
