"""`tactilepipe provenance --crate DIR`: a build's provenance as an RO-Crate others can read."""

from __future__ import annotations

from tactilepipe.cli.registry import arg, command


@command("provenance", "write a build's provenance as a Workflow Run RO-Crate: the workflow at its commit, each "
                       "scene's inputs with DVC's hashes, parameter values, outputs, machine, packages and times",
         args=(arg("--crate", required=True, metavar="DIR", help="the crate's folder (written, created if missing)"),
               arg("--build", help="the build, results/<build>/ (default: the build params.yaml names at its scale)"),
               arg("--agent", help="who ran the build: a name or an ORCID URL (default: git's user.name)"),
               arg("--repo", default=".", help="the project (default: here)")))
def cmd_provenance(args, p) -> int:
    from pathlib import Path

    from tactilepipe.pipeline.crate import write_crate
    repo = Path(args.repo)
    if args.build is None:
        from tactilepipe.studies import load_params
        args.build = load_params(repo / "params.yaml")["build"]
    crate = write_crate(repo, args.build, Path(args.crate), args.agent)
    actions = [e for e in crate.get_entities() if e.type == "CreateAction"]
    timed = sum(1 for a in actions if a.get("endTime"))
    print(f"{args.crate}: RO-Crate of results/{args.build}/, {len(actions)} runs ({timed} with Snakemake's "
          f"start and end times), {len(crate.data_entities)} files")
    return 0
