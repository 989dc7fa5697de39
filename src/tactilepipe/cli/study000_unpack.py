"""Stage of study 000 on its own data: check a published archive and unpack it into a session."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.tool.checks import check as tool_check


@command("study000-unpack", "check a study-000 archive's size and sha256, unpack it into a public-layout session",
         checks=(tool_check,),
         params=("public_data.files", "public_data.session"),
         args=(arg("archive", help="e.g. raw/downloads/data_normal.zip"),
               arg("--name", required=True, help="its entry in params.yaml public_data.files (data_normal, data_shear)"),
               arg("--raw-root", default="raw/tool", help="the session folder public_data.session is made here")))
def cmd_study000_unpack(args, p) -> None:
    from tactilepipe.tool.formats.public_archive import unpack, verify_listed, write_trials_template
    verify_listed(args.archive, p["public_data"]["files"], args.name, "--name")
    session = Path(args.raw_root) / p["public_data"]["session"]
    trials = unpack(args.archive, args.name, session)
    added = write_trials_template(session)
    print(json.dumps({"archive": args.archive, "session": str(session), "trials": len(trials),
                      "trials_csv_rows_added": len(added)}))
    if added:
        print(f"{session / 'trials.csv'}: {len(added)} trials need a tool and pose (tool, orientation_deg, "
              f"insertion_mm) before the scene can be built", file=sys.stderr)
