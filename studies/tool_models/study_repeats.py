"""How the study's verdicts depend on the number of repeated splits, read from a build (no training).

A repeat's split and model seed depend only on its index (tool/data/splits.py, tool/runs.py), so
the first K repeats of a build with more are exactly what a build with ``tool_split.repeats: K``
trains. This judges every ordering of the tool report (tool/report/verdicts.py, with the margin
taken from those K repeats as the report takes it) on the first K per-split scores of each scene's
``scores.json``, for each K from --min-repeats to the build's repeats, and prints how many are
decided. The intervals use the whole build's n_test/n_train; a K-repeat build uses its own K
splits' mean, which moves a half-width by well under 1 % here (0.249 at 12 and 16 on normal force).

    python studies/tool_models/study_repeats.py [--build results/default] [--min-repeats 3]

Reads two JSON files; runs in about a second.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from tactilepipe.tool.report.verdicts import METRICS, PAPER_ORDERINGS, judge, margin_n, paper_orderings

# the models the study's orderings name (the report's own list), and full's like-for-like baseline
VARIANTS = sorted({v for pairs in PAPER_ORDERINGS.values() for pair in pairs for v in pair})
SHORT = {"holds": "holds", "reversed": "reversed", "equivalent": "equiv.", "undecided": "-"}


def first_k(scores: dict, k: int) -> dict[str, dict[str, list[float]]]:
    """Each variant's and full's like-for-like baseline's per-split scores, the first ``k`` splits."""
    baseline = scores["full"]["like_for_like_baseline"]
    out = {v: {m: scores[v]["per_split"][m][:k] for m in METRICS} for v in VARIANTS}
    out[baseline] = {m: scores["baselines"][baseline]["per_split"][m][:k] for m in METRICS}
    return out


def verdicts(scores: dict, scene: str, k: int) -> list[tuple[str, str]]:
    """(claim, verdict) of each ordering of ``scene`` and of full against its baseline, on ``k`` splits,
    judged as the report judges them (verdicts.paper_orderings, verdicts.judge)."""
    sub = first_k(scores, k)
    margin = margin_n(sub, scores["equivalence_margin"]["fraction_of_full_mae"])
    ratio = scores["test_train_ratio"]
    judged = paper_orderings(scene, sub, ratio, margin) + \
        [judge("full", scores["full"]["like_for_like_baseline"], sub, margin, ratio)]
    return [(f"{scene.removeprefix('tool_')}: {j['better']} < {j['worse']}", j["verdict"]) for j in judged]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--build", type=Path, default=Path("results/default"))
    parser.add_argument("--min-repeats", type=int, default=3)
    args = parser.parse_args(argv)
    scores = {s: json.loads((args.build / s / "scores.json").read_text()) for s in PAPER_ORDERINGS}
    missing = {s: [v for v in VARIANTS if v not in m] for s, m in scores.items()}
    if any(missing.values()):
        raise SystemExit(f"study_repeats: {args.build} lacks variants {missing}: it judges builds of all four")
    repeats = min(s["repeats"] for s in scores.values())
    if repeats < max(args.min_repeats, 2):
        raise SystemExit(f"study_repeats: {args.build} has {repeats} repeats, fewer than --min-repeats {args.min_repeats}")
    rows = []
    for k in range(max(args.min_repeats, 2), repeats + 1):
        judged = [v for scene in PAPER_ORDERINGS for v in verdicts(scores[scene], scene, k)]
        orderings = [v for claim, v in judged if claim.split(" < ")[1] in VARIANTS]
        rows.append((k, sum(v != "undecided" for v in orderings), len(orderings), judged))
    claims = [claim for claim, _ in rows[0][3]]
    print(f"Verdicts on the first K of {repeats} repeated splits ({args.build}); '-': undecided\n")
    print("| K | decided | " + " | ".join(claims) + " |")
    print("|---|---|" + "---|" * len(claims))
    for k, decided, total, judged in rows:
        print(f"| {k} | {decided} of {total} | " + " | ".join(SHORT[v] for _, v in judged) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
