"""Two runs of the pipeline compared metric by metric, each change classed as signal or noise.

A run is a git revision, a DVC experiment or the workspace; its files are read through DVC
(``dvc.api.read``), so each is what `dvc metrics diff` and `dvc exp show` see. For every scene:

- **scored series**, a score measured on repeated draws: each tool model's (variant's and
  baseline's) MAE, RMSE and R² over the repeated splits, each volume input's R² over the folds.
  When both runs drew the same splits (the same recordings, and the same code and parameters of
  every stage before the models: ``provenance.json``), the change is judged **paired**: the
  interval of the per-draw differences (the same corrected resampled t as the reports) either
  excludes zero (signal) or not (noise). A run with more repeats than the other is paired over the
  draws both have (a tool scene's draws are named by their split, and repeat k draws from its own
  seed whatever the count); otherwise the two runs' own intervals are compared: disjoint is signal,
  overlapping noise.
- **non-finite**: a score that is NaN, infinite or null in the new run (its mean or any one draw)
  is never noise: it is its own verdict, and a metric held to a tolerance fails on it.
- **single values** (the drift fits, the volume table, ...): the pipeline makes them
  deterministically, so any change is reported as changed, with no noise estimate; but a value
  (or every draw of a score) within ``ROUNDING`` of the other, relative, is ``rounding``: the same
  arithmetic summed in another order (another CPU's vector width in NumPy or BLAS).

A scene's verdict is one line: unchanged, changes within noise only, or the signals, worst first.

A run's files are read by ``run_files.py``: a tool scene's scores from its ``scores.json`` (its
``metrics/`` is their headline), and earlier revisions' layouts in today's.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field

from tactilepipe.core.intervals import paired_difference
from tactilepipe.core.study import same_value as _same
from tactilepipe.pipeline.run_files import current_layout, read_run  # noqa: F401 (read_run: diff's reader)
from tactilepipe.pipeline.scenes import SCENES as SCENE_TABLE
from tactilepipe.pipeline.scenes import contract
from tactilepipe.studies import contracts

CONTRACTS = contracts()
SCENES = tuple(SCENE_TABLE)
# stages whose change leaves the draws (splits, folds) alone: the models and their report (each study's)
MODEL_STAGES = set().union(*(c.scores.MODEL_STAGES for c in CONTRACTS.values()))
LOWER_IS_BETTER = {"mae", "rmse"}
HIGHER_IS_BETTER = {"r2", "loo_r2"}


def _scores(scene: str):
    """How the scene's study lays out its scores.json (its contract's scores_layout.py)."""
    return contract(scene).scores


@dataclass
class Row:
    scene: str
    model: str
    metric: str
    old: float | str | bool | None
    new: float | str | bool | None
    verdict: str                       # same | noise | signal | non-finite | changed | rounding | added | removed
    how: str = ""                      # paired over K draws | intervals | single value
    low: float = math.nan              # interval of the change, where judged
    high: float = math.nan
    nonfinite: bool = False            # the new value (or one of its draws) is NaN, infinite or null
    paired_mean: float = math.nan      # mean per-draw change, where paired over a subset of the draws

    @property
    def change(self) -> float:
        """new - old; paired over the draws two runs share (not all of either's), the mean change
        over those draws, since the means over all draws differ by the extra draws' luck."""
        if not math.isnan(self.paired_mean):
            return self.paired_mean
        numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (self.old, self.new))
        return (self.new - self.old) if numbers else math.nan

    @property
    def label(self) -> str:
        return f"{self.model} {self.metric}" if self.model else self.metric

    @property
    def worse_by(self) -> float:
        """How much worse the new value is: for an error or a score, 0 when better; for a value
        with no better direction, any change (NaN without two numbers)."""
        c = self.change
        if math.isnan(c):
            return math.nan
        name = self.metric.rsplit(".", 1)[-1]
        if name in LOWER_IS_BETTER:
            return max(c, 0.0)
        return max(-c, 0.0) if name in HIGHER_IS_BETTER else abs(c)


@dataclass
class SceneDiff:
    scene: str
    rows: list[Row] = field(default_factory=list)
    note: str = ""                      # why a scene is not compared (absent from a run)

    @property
    def scored(self) -> bool:
        """Scored over repeated draws: judged by those scores, its single values counted beside."""
        return any(r.how != "single value" for r in self.rows)

    @property
    def verdict(self) -> str:
        if self.note:
            return self.note
        rounded = [r for r in self.rows if r.verdict == "rounding"]
        moved = [r for r in self.rows if r.verdict not in ("same", "rounding")]
        largest = max((abs(r.change) / (max(abs(r.old), abs(r.new)) or 1.0) for r in rounded), default=0.0)
        last = f"{len(rounded)} values differ in their last digits only (at most {largest:.1g} relative)" if rounded else ""
        if not moved:
            return f"unchanged but for rounding: {last}" if rounded else "unchanged"
        # a scene scored over repeated draws is judged by those scores; its single values (derived
        # from the same models) are counted beside them. A scene without draws by its values.
        judged = [r for r in moved if (r.how != "single value") == self.scored]
        others = len(moved) - len(judged)
        # a value that is no longer a number first: it is worse than any size of change
        signals = sorted((r for r in judged if r.verdict != "noise"),
                         key=lambda r: -math.inf if r.nonfinite else -(r.worse_by if not math.isnan(r.worse_by) else -1))
        tail = (f"; {others} other values changed" if others else "") + (f"; {last}" if last else "")
        if not judged:
            return f"scores unchanged{tail}"
        if not signals:
            return f"{len(judged)} changes, all within noise{tail}"
        shown = ", ".join(f"{r.label} {_signed(r.change)} ({r.verdict})" if not math.isnan(r.change)
                          else f"{r.label} {r.verdict}" for r in signals[:3])
        more = f" and {len(signals) - 3} more" if len(signals) > 3 else ""
        return f"{len(signals)} beyond noise: {shown}{more}{tail}"


# ----------------------------------------------------------------------------- reading a run

def draws_identity(provenance: dict | None, scene: str) -> str | None:
    """What fixes a scene's draws: its recordings (by DVC's hash; older runs' own sha256 pairs only
    with its kind) and every stage before the models (code, parameters): same identity, same draws.
    Only the stages its study lists for the scene, and its simulator, count: another stage that
    declares its rule in the scene (a summary, a figure) makes no draw."""
    if not provenance:
        return None
    own = set(SCENE_TABLE[scene].stages) | {contract(scene).SIMULATOR}
    key = {"sessions": provenance.get("sessions"),
           "stages": {s: v for s, v in sorted(provenance.get("stages", {}).items())
                      if s in own and s not in MODEL_STAGES}}
    return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()


# ----------------------------------------------------------------------------- what a scene scores

def scored_series(scene: str, metrics: dict) -> dict[tuple[str, str], dict]:
    """``{(model, metric): {"value", "draws", "names", "low", "high"}}`` of the scores over repeated
    draws; ``names`` names each draw (a tool scene's split), None where draws are only counted."""
    return _scores(scene).scored_series(metrics)


def _nonfinite(value) -> bool:
    """None, NaN or an infinity: a value that is no longer a number (text and flags are not numbers
    to begin with)."""
    return value is None or (isinstance(value, float) and not math.isfinite(value))


def draws_shown_same(scene: str, old: dict, new: dict) -> set[str]:
    """The draws two runs demonstrably share, whatever their provenance says (a tool scene's: the
    splits on which every baseline scores exactly the same; tool/scores_layout.py)."""
    return _scores(scene).draws_shown_same(old, new)


def shared_draws(sa: dict, sb: dict, only: set[str] | None = None) -> tuple[list[float], list[float]] | None:
    """The scores of the draws both series have, in the same order: by name when both name their
    draws (a 6-repeat run against an 8-repeat one: the 6 shared splits; ``only``: just these
    names), by position when neither does and the counts agree; None when they cannot be paired."""
    if sa["names"] is not None and sb["names"] is not None:
        at = {name: i for i, name in enumerate(sb["names"])}
        common = [(i, at[name]) for i, name in enumerate(sa["names"])
                  if name in at and (only is None or name in only)]
        return [sa["draws"][i] for i, _ in common], [sb["draws"][j] for _, j in common]
    if len(sa["draws"]) == len(sb["draws"]):
        return sa["draws"], sb["draws"]
    return None


def single_values(scene: str, metrics: dict) -> dict[str, float | str | bool]:
    """Every other number, verdict and name of the scene, by its dotted path (lists by index)."""
    layout = _scores(scene)
    skip, scored = layout.SINGLE_SKIP, layout.scored_keys
    out = {}

    def walk(node, path):
        if node is None:                  # a null is kept: a value that became null has changed
            out[path] = None
        elif isinstance(node, (bool, str)):
            out[path] = node
        elif isinstance(node, (int, float)):
            out[path] = float(node)
        elif isinstance(node, dict):
            for k, v in node.items():
                # a model's top-level scores are the means of its scored series: compared there, not twice
                if k not in skip and k not in scored(node):
                    walk(v, f"{path}.{k}" if path else str(k))
        elif isinstance(node, list):
            for i, v in enumerate(node):
                walk(v, f"{path}.{i}")
    walk(metrics, "")
    return out


# ----------------------------------------------------------------------------- comparing

# Relative difference within which two values are the same arithmetic rounded otherwise (sums in
# another order, an iterative fit carrying that further): measured up to 8e-13 between the default
# drift fits of an AVX-512 and an AVX2 machine. 1e-9 keeps 9 digits, more than any report shows.
ROUNDING = 1e-9


def _rounding_only(a, b) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in (a, b)) \
        and abs(a - b) <= ROUNDING * max(abs(a), abs(b))


def _test_train_ratio(scene: str, run: dict) -> float:
    """n_test/n_train of one draw, for the corrected resampled t the reports use (the study says where)."""
    return _scores(scene).test_train_ratio(run)


def compare_scene(scene: str, old: dict | None, new: dict | None) -> SceneDiff:
    if old is None or new is None:
        which = "either run" if old is None and new is None else ("the old run" if old is None else "the new run")
        return SceneDiff(scene, note=f"not in {which}")
    out = SceneDiff(scene)
    old, new = ({**run, "metrics": current_layout(scene, run["metrics"])} for run in (old, new))
    paired = draws_identity(old["provenance"], scene) == draws_identity(new["provenance"], scene) is not None
    # otherwise the draws whose baselines show them to be the same splits (a tool scene)
    shown = None if paired else draws_shown_same(scene, old["metrics"], new["metrics"])
    ratio = _test_train_ratio(scene, new)
    a, b = scored_series(scene, old["metrics"]), scored_series(scene, new["metrics"])
    for key in sorted(set(a) | set(b)):
        model, metric = key
        if key not in b or key not in a:
            s = a.get(key) or b.get(key)
            out.rows.append(Row(scene, model, metric, s["value"] if key in a else None,
                                s["value"] if key in b else None, "removed" if key not in b else "added",
                                nonfinite=key in b and (_nonfinite(s["value"]) or any(map(_nonfinite, s["draws"])))))
            continue
        sa, sb = a[key], b[key]
        bad = _nonfinite(sb["value"]) or any(map(_nonfinite, sb["draws"]))
        pairs = shared_draws(sa, sb) if paired else (shared_draws(sa, sb, shown) if shown else None)
        same_count, draws = len(sa["draws"]) == len(sb["draws"]), list(zip(sa["draws"], sb["draws"]))
        if same_count and all(_same(x, y) for x, y in draws):
            out.rows.append(Row(scene, model, metric, sa["value"], sb["value"], "same", nonfinite=bad))
        elif same_count and not bad and all(_same(x, y) or _rounding_only(x, y) for x, y in draws):
            out.rows.append(Row(scene, model, metric, sa["value"], sb["value"], "rounding", "every draw"))
        elif bad:                          # never noise, whatever the interval of the finite draws says
            out.rows.append(Row(scene, model, metric, sa["value"], sb["value"], "non-finite", nonfinite=True))
        elif pairs is not None and len(pairs[0]) >= 2:
            d = paired_difference(pairs[1], pairs[0], test_train_ratio=ratio)
            shared = "" if len(pairs[0]) == len(sa["draws"]) == len(sb["draws"]) else " shared"
            out.rows.append(Row(scene, model, metric, sa["value"], sb["value"],
                                "signal" if d["excludes_zero"] else "noise", f"paired over {d['n']}{shared} draws",
                                d["low"], d["high"], paired_mean=d["mean"] if shared else math.nan))
        else:
            apart = sb["low"] > sa["high"] or sb["high"] < sa["low"]
            out.rows.append(Row(scene, model, metric, sa["value"], sb["value"], "signal" if apart else "noise",
                                "intervals"))
    va, vb = single_values(scene, old["metrics"]), single_values(scene, new["metrics"])
    for path in sorted(set(va) | set(vb)):
        if path in va and path in vb:
            a, b = va[path], vb[path]
            verdict = "same" if _same(a, b) else ("rounding" if _rounding_only(a, b) else "changed")
        else:
            verdict = "removed" if path not in vb else "added"
        out.rows.append(Row(scene, "", path, va.get(path), vb.get(path), verdict, "single value",
                            nonfinite=path in vb and _nonfinite(vb[path])))
    return out


def diff_runs(old: dict, new: dict, scenes=SCENES) -> list[SceneDiff]:
    return [compare_scene(s, old.get(s), new.get(s)) for s in scenes]


def failures(diffs: list[SceneDiff], tolerances: dict[str, float]) -> list[Row]:
    """Rows whose metric (its last name: mae, r2, ...) got worse by more than its tolerance, or is
    no longer a number in the new run (NaN, infinite or null, in its mean or any draw: worse than
    any tolerance, and never noise). A scene scored over draws is held to its scores (their
    means), not to single draws' values. A difference in rounding only is no change, even at
    a tolerance of 0."""
    out = []
    for d in diffs:
        for r in d.rows:
            name = r.metric.rsplit(".", 1)[-1]
            if (r.how != "single value") != d.scored or name not in tolerances or r.verdict == "rounding":
                continue
            if r.nonfinite or (not math.isnan(r.worse_by) and r.worse_by > tolerances[name]):
                out.append(r)
    return out


# ----------------------------------------------------------------------------- output

def _signed(x: float) -> str:
    return f"{x:+.4g}"


def _num(x) -> str:
    if x is None or isinstance(x, (bool, str)):
        return "" if x is None else str(x)
    return "NaN" if math.isnan(x) else f"{x:.4g}"


def markdown(diffs: list[SceneDiff], old_name: str, new_name: str, show_same: bool = False) -> str:
    lines = [f"## Metrics: {old_name} → {new_name}", ""]
    lines += [f"- **{d.scene}**: {d.verdict}" for d in diffs]
    for d in diffs:
        # a scene scored over draws lists its scores; the single values derived from the same
        # models (counted in the verdict) only with show_same
        rows = [r for r in d.rows if show_same or (r.verdict != "same" and not (d.scored and r.how == "single value"))]
        if not rows:
            continue
        lines += ["", f"### {d.scene}", "", "| model | metric | old | new | change | verdict | judged by |",
                  "|---|---|---|---|---|---|---|"]
        for r in rows:
            judged = r.how + (f", change in [{r.low:.3g}, {r.high:.3g}]" if not math.isnan(r.low) else "")
            change = _signed(r.change) if not math.isnan(r.change) else ""
            lines.append(f"| {r.model} | {r.metric} | {_num(r.old)} | {_num(r.new)} | {change} | {r.verdict} | {judged} |")
    return "\n".join(lines) + "\n"


def as_json(diffs: list[SceneDiff]) -> dict:
    return {d.scene: {"verdict": d.verdict,
                      "rows": [{"model": r.model, "metric": r.metric, "old": r.old, "new": r.new,
                                "change": None if math.isnan(r.change) else r.change,
                                "worse_by": None if math.isnan(r.worse_by) else r.worse_by, "verdict": r.verdict,
                                "how": r.how, "nonfinite": r.nonfinite} for r in d.rows if r.verdict != "same" or r.nonfinite]} for d in diffs}
