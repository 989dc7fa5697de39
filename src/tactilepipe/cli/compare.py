"""Comparing runs and records: `tactilepipe diff` (two runs' metrics) and `tactilepipe verify-data`
(the workspace's files against DVC's records)."""

from __future__ import annotations

import json
import math
import sys

from tactilepipe.cli.registry import arg, command
from tactilepipe.core.errors import ArgumentError


def _tolerances(items: list[str]) -> dict[str, float]:
    out = {}
    for item in items:
        name, _, value = item.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ArgumentError(f"--fail-on {item!r}: expected METRIC=TOLERANCE, e.g. mae=0.05") from None
        # every comparison with NaN is false, so a NaN tolerance would pass any change; an infinite
        # one passes every change, a negative one fails an unchanged run
        if not math.isfinite(out[name.strip()]) or out[name.strip()] < 0:
            raise ArgumentError(f"--fail-on {item!r}: the tolerance must be a finite number >= 0, e.g. mae=0.05")
    return out


@command("diff", "compare the metrics of two runs (git revisions, DVC experiments or the workspace), each change "
                 "classed as signal or noise",
         args=(arg("revs", nargs="*", metavar="RUN",
                   help="none: HEAD against the workspace; one: it against the workspace; two: the first against "
                        "the second. A git revision or a DVC experiment's name"),
               arg("--scenes", nargs="+", help="only these scenes (default: every scene)"),
               arg("--build", help="the build compared, results/<build>/ (default: the build params.yaml names "
                                   "at its scale, results/default/ for the committed results)"),
               arg("--fail-on", nargs="+", default=[], metavar="METRIC=TOL",
                   help="exit 1 when a metric (mae, rmse, r2, or a value's last name) of any model got worse by "
                        "more than TOL (finite, >= 0), or is NaN or null in the new run, e.g. --fail-on mae=0.05 "
                        "r2=0.01"),
               arg("--json", action="store_true", help="JSON instead of Markdown"),
               arg("--all", action="store_true", help="also list what did not change"),
               arg("--out", help="write the report here instead of standard output"),
               arg("--repo", default=".", help="the project (default: here)")))
def cmd_diff(args, p) -> int:
    from tactilepipe.core.atomic import write_text
    from tactilepipe.pipeline import diff
    if len(args.revs) > 2:
        raise ArgumentError(f"diff takes at most two runs, got {len(args.revs)}: {' '.join(args.revs)}")
    tolerances = _tolerances(args.fail_on)
    old_rev = args.revs[0] if args.revs else "HEAD"
    new_rev = args.revs[1] if len(args.revs) == 2 else None
    scenes = args.scenes or list(diff.SCENES)
    unknown = set(scenes) - set(diff.SCENES)
    if unknown:
        raise ArgumentError(f"unknown scene(s) {', '.join(sorted(unknown))} (one of {', '.join(diff.SCENES)})")
    if args.build is None:
        from pathlib import Path

        from tactilepipe.studies import load_params
        params = Path(args.repo) / "params.yaml"       # a remote --repo: the default scale's build
        args.build = load_params(params)["build"] if params.is_file() else "default"
    diffs = diff.diff_runs(diff.read_run(old_rev, args.repo, scenes, args.build),
                           diff.read_run(new_rev, args.repo, scenes, args.build), scenes)
    names = {r.metric.rsplit(".", 1)[-1] for d in diffs for r in d.rows}
    unknown_metrics = sorted(set(tolerances) - names)
    if unknown_metrics:
        raise ArgumentError(f"--fail-on {', '.join(unknown_metrics)}: no such metric in these runs (e.g. "
                            f"{', '.join(sorted(names & {'mae', 'rmse', 'r2'}) or sorted(names)[:3])})")
    text = (json.dumps(diff.as_json(diffs), indent=1, sort_keys=True) + "\n" if args.json
            else diff.markdown(diffs, old_rev, new_rev or "workspace", show_same=args.all))
    if args.out:
        write_text(args.out, text)
    else:
        sys.stdout.write(text)
    failed = diff.failures(diffs, tolerances)
    for r in failed:
        tol = tolerances[r.metric.rsplit('.', 1)[-1]]
        if r.nonfinite:
            print(f"tactilepipe diff: {r.scene}: {r.label} is not a number in the new run ({_text(r.new)}, or a "
                  f"draw of it NaN or null): a regression at any tolerance (tolerance {tol:g})", file=sys.stderr)
        else:
            print(f"tactilepipe diff: {r.scene}: {r.label} worse by {r.worse_by:.4g} (tolerance {tol:g}; {r.verdict})",
                  file=sys.stderr)
    return 1 if failed else 0


def _text(value) -> str:
    return "null" if value is None else str(value)


@command("verify-data", "re-hash every file DVC tracks (dvc.lock, .dvc files) and name those whose content "
                        "differs from the record (dvc status trusts file times)",
         args=(arg("--repo", default=".", help="the project (default: here)"),))
def cmd_verify_data(args, p) -> int:
    from tactilepipe.pipeline.verify import verify_workspace
    checked, problems = verify_workspace(args.repo)
    for line in problems:
        print(line)
    print(f"{checked} files tracked by DVC re-hashed: {len(problems)} differ from their records"
          + ("" if not problems else " (dvc checkout --relink restores them from a sound cache; dvc pull from the "
                                     "remote when the cache is corrupt too)"))
    return 1 if problems else 0
