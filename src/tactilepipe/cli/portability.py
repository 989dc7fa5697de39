"""Command of the tool study: a smoke build's runs against the record of bytes per machine kind."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.registry import arg, command


@command("portability", "compare a smoke build's tool runs with results/portability.json: the same bytes on "
                        "every machine kind (adds this one when new)",
         args=(arg("--results", default="results/smoke", help="results folder of a smoke-scale build (make smoke)"),
               arg("--record", default="results/portability.json", help="the record to check and extend"),
               arg("--new", action="store_true",
                   help="start the record again from this build and machine (after a deliberate change of the "
                        "training code, its parameters or the data)")))
def cmd_portability(args, p) -> None:
    from tactilepipe.core.atomic import write_json
    from tactilepipe.tool.report import portability
    results, record = Path(args.results), Path(args.record)
    if args.new:
        rec = portability.new_record(results)
        write_json(record, rec)
        print(f"{record}: started with {len(rec['runs'])} runs on {portability.describe(rec['machines'][0]['kind'])}")
        return
    for note in portability.check(results, record):
        print(f"{record}: {note}")
