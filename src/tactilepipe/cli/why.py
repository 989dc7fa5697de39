"""`tactilepipe why <output>`: the jobs that would re-make an output, or last made it, and why."""

from __future__ import annotations

from tactilepipe.cli.registry import arg, command


@command("why", "which jobs would re-make an output (with the changed file, input or parameter key), or when and "
                "why it was last made",
         args=(arg("outputs", nargs="+", help="files the workflow makes (e.g. results/default/tool_normal/metrics/full.json)"),
               arg("--repo", default=".", help="the project (default: here)")))
def cmd_why(args, p) -> int:
    import subprocess
    import sys
    from pathlib import Path

    from tactilepipe.core.errors import TactilepipeError
    from tactilepipe.pipeline.why import explain
    repo = Path(args.repo)
    snakemake = Path(sys.executable).with_name("snakemake")
    logs = sorted((repo / ".snakemake/log").glob("*.snakemake.log"), reverse=True)
    for target in args.outputs:
        proc = subprocess.run([str(snakemake if snakemake.exists() else "snakemake"), "-n", "--cores", "1",
                               "--workflow-profile", "workflow/profiles/default", target],
                              cwd=repo, capture_output=True, text=True)
        if proc.returncode != 0:
            last = (proc.stderr.strip() or proc.stdout.strip() or "no message").splitlines()[-1]
            raise TactilepipeError(f"{target}: Snakemake cannot plan it: {last}")
        print(explain(target, proc.stdout + proc.stderr, logs))
    return 0
