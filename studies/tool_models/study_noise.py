"""Where the noise of the study's orderings comes from: split composition, model seed or test sampling.

Each ordering of the tool report (full < no_gam, ..., full against the tactile-RMSE linear fit) is a
paired MAE difference over the repeated trial splits. This retrains each variant on the first
``--splits`` splits of a built scene with ``--seeds`` model seeds each (seed 0 is the build's own run,
reused; seed m adds 1000 m to params.yaml ``seed``), and splits the variance of every paired
difference into split composition, model seed and test sampling (tool/report/noise.py). It prints
one table per scene: each component's standard deviation, the interval half-width of today's design
(K repeats, one seed) and of designs with more repeats or seeds, and what a run costs.

A second table asks what any design of this data size decides, at the build's mean difference
(its scores.json, all its repeats): the half-width's floor with endless repeats and seeds (the split
term holds at least the test sampling every seed shares, which only more test trials shrink; a
run's own test sampling also holds its seed's errors on those trials, which an ensemble of the
split's seeds thins, so the shared part is read from the two), and the repeats K that decide the
ordering at even odds (the interval just reaches the mean) under the report's interval and under
the components' model (the seed's share falling as 1/K), and with 80 % power with one seed per
split or a prediction ensemble of the seeds.

Needs a built scene (`make run`). Runs go to --work-dir and are reused when the script runs again.
    python studies/tool_models/study_noise.py [--scenes tool_normal tool_shear] [--splits 3] [--seeds 3] [--jobs 2]
About 100 s per training run on one core at the default scale (width 32, 8 epochs).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from tactilepipe.core.atomic import write_json
from tactilepipe.core.intervals import half_width as interval_half_width, repeats_for_half_width
from tactilepipe.tool.data.loader import ToolFrames
from tactilepipe.tool.model.evaluate import linear_fit_predictions, tactile_rmse_features
from tactilepipe.tool.report.noise import bootstrap_difference_variance, decompose, half_width
from tactilepipe.tool.scenes import scene_label

REPO = Path(__file__).resolve().parents[2]
BASELINE = "tactile_rmse_linear"
ORDERINGS = {   # (better, worse) as the report claims them (tool/report/verdicts.py)
    "tool_normal": [("full", "no_gam"), ("full", "no_ref"), ("full", "single"), ("no_gam", "no_ref"),
                    ("no_ref", "single"), ("full", BASELINE)],
    "tool_shear": [("full", "no_gam"), ("full", "no_ref"), ("full", "single"), ("full", BASELINE)],
}
DESIGNS = [(8, 1), (8, 2), (16, 1), (8, 4), (32, 1)]   # (repeats K, seeds per split M)


def run_name(variant: str, k: int) -> str:
    return variant if k == 0 else f"{variant}_r{k}"


def split_name(k: int) -> str:
    return "trial" if k == 0 else f"trial_r{k}"


def train(args, scene: str, variant: str, k: int, m: int) -> Path:
    """The run's folder: the build's own for seed 0, else trained (once) under --work-dir."""
    scene_dir = args.build_dir / scene
    if m == 0:
        return scene_dir / "models" / run_name(variant, k)
    out = args.work_dir / scene / f"{run_name(variant, k)}_m{m}"
    if (out / "eval.json").exists():
        return out
    seed = json.loads((args.build_dir / "params/tool-train" / f"{run_name(variant, k)}.json").read_text())["values"]["seed"]
    cmd = [sys.executable, "-m", "tactilepipe", "tool-train", "--scale", args.scale,
           "--override", json.dumps({"seed": seed + 1000 * m}), "--run", run_name(variant, k), "--scene", scene,
           "--data-dir", str(scene_dir / "data"), "--split", str(scene_dir / "splits" / f"{split_name(k)}.json"),
           "--out-dir", str(out), "--quiet"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"study_noise: {' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    print(f"  trained {scene} {run_name(variant, k)} seed {m} in {time.perf_counter() - t0:.0f} s", flush=True)
    return out


def baseline_errors(args, scene: str, splits: list[dict]) -> list[pd.Series]:
    """|error| of the tactile-RMSE linear fit on each split's test rows, by sample index
    (deterministic: no seed). The frames are read and their features computed once per scene."""
    data = ToolFrames(args.build_dir / scene / "data", scene_label(scene))
    features = tactile_rmse_features(data.frames, data.references, data.trial_index)
    errors = []
    for split in splits:
        test = np.asarray(split["test"])
        pred = linear_fit_predictions(data.labels, features, split)
        errors.append(pd.Series(np.abs(pred - data.labels[test]), index=test))
    return errors


def errors(run_dir: Path) -> pd.DataFrame:
    p = pd.read_parquet(run_dir / "predictions.parquet").set_index("index")
    return p.assign(abs_err=(p["pred"] - p["true"]).abs())


def ensemble(runs: dict, variant: str, k: int, seeds: int) -> pd.DataFrame:
    """The seeds' predictions on split k averaged (one model's worth of test rows)."""
    first = runs[(variant, k, 0)]
    pred = np.mean([runs[(variant, k, m)]["pred"].reindex(first.index) for m in range(seeds)], axis=0)
    return first.assign(pred=pred, abs_err=np.abs(pred - first["true"]))


def repeats_to_decide(need: float, var_split: float, var_seed: float, ratio: float, power: float) -> int | None:
    """Fewest K (one seed, or one ensemble, per split) whose interval under the components' model
    (tool/report/noise.py half_width), widened by the power's z, fits inside ``need``; None when none
    up to 1,000 does."""
    if not need > 0:
        return None
    parts = {"var_split": var_split, "var_seed": var_seed, "test_train_ratio": ratio}
    z = stats.norm.ppf(power) if power > 0.5 else 0.0
    for k in range(2, 1001):
        h = half_width(parts, k, 1)                      # t(0.975, K - 1) x standard error
        if h * (1 + z / stats.t.ppf(0.975, k - 1)) <= need:
            return k
    return None


def shared_test_variance(var_test_one: float, var_test_ensemble: float, seeds: int) -> float:
    """The test sampling every seed shares. A run's bootstrap variance holds it plus the seeds' own
    errors on those trials; an ensemble of ``seeds`` keeps 1/seeds of the latter, so the shared part
    is (seeds v_ensemble - v_one) / (seeds - 1) (0 when that comes out negative)."""
    return max(0.0, (seeds * var_test_ensemble - var_test_one) / (seeds - 1))


def decidable(parts: dict, built: dict, var_test_ensemble: float, seeds: int) -> dict:
    """What designs of this data size can decide, at the build's mean difference and margin. The
    split term is taken as at least the test sampling the seeds share (no seed design removes it);
    K under the report's interval (all the spread widened by n_test/n_train, verdicts.power_line) and
    under the components' model (the seed's share falling as 1/K), with one seed per split or an
    ensemble of ``seeds`` (its seed variance a 1/seeds share)."""
    shared = shared_test_variance(parts["var_test"], var_test_ensemble, seeds)
    var_split = max(parts["var_split"], shared)
    ratio, mean, margin = parts["test_train_ratio"], abs(built["mae_difference"]), built["margin"]
    need = max(mean, margin - mean) if math.isfinite(margin) else mean   # exclude 0, or fit the margin
    return {"built_mean": built["mae_difference"], "built_verdict": built["verdict"], "need": need,
            "var_test_shared": shared,
            "floor": interval_half_width(math.sqrt(var_split), math.inf, test_train_ratio=ratio),
            "K_report": repeats_for_half_width(math.sqrt(var_split + parts["var_seed"]), need,
                                               test_train_ratio=ratio),
            "K_even": repeats_to_decide(need, var_split, parts["var_seed"], ratio, 0.5),
            "K_80": repeats_to_decide(need, var_split, parts["var_seed"], ratio, 0.8),
            "K_80_ensemble": repeats_to_decide(need, var_split, parts["var_seed"] / seeds, ratio, 0.8)}


def study_scene(args, scene: str, pool: ThreadPoolExecutor) -> dict:
    variants = sorted({v for pair in ORDERINGS[scene] for v in pair if v != BASELINE})
    jobs = {(v, k, m): pool.submit(train, args, scene, v, k, m)
            for m in range(args.seeds) for k in range(args.splits) for v in variants}
    runs = {key: errors(job.result()) for key, job in jobs.items()}
    costs = [json.loads((jobs[key].result() / "eval.json").read_text())["train_s"] for key in jobs]
    splits = [json.loads((args.build_dir / scene / "splits" / f"{split_name(k)}.json").read_text())
              for k in range(args.splits)]
    base = dict(enumerate(baseline_errors(args, scene, splits)))
    ratio = float(np.mean([len(s["test"]) / len(s["train"]) for s in splits]))
    scores = json.loads((args.build_dir / scene / "scores.json").read_text())
    built = {(o["better"], o["worse"]): o for o in scores["paper_orderings"] + [scores["full_versus_baseline"]]}
    rows = []
    for better, worse in ORDERINGS[scene]:
        d = np.zeros((args.splits, args.seeds))
        tv = np.zeros_like(d)
        for k in range(args.splits):
            for m in range(args.seeds):
                a = runs[(better, k, m)]
                b = base[k] if worse == BASELINE else runs[(worse, k, m)]["abs_err"]
                b = b.reindex(a.index)
                d[k, m] = a["abs_err"].mean() - b.mean()
                tv[k, m] = bootstrap_difference_variance(a["abs_err"], b, a["trial"], seed=k * 100 + m)
        parts = decompose(d, tv, ratio)
        ens_tv = []
        for k in range(args.splits):
            a = ensemble(runs, better, k, args.seeds)
            b = base[k] if worse == BASELINE else ensemble(runs, worse, k, args.seeds)["abs_err"]
            ens_tv.append(bootstrap_difference_variance(a["abs_err"], b.reindex(a.index), a["trial"], seed=k * 100))
        var_test_ensemble = float(np.nanmean(ens_tv))
        rows.append({"ordering": f"{better} < {worse}", **parts, "var_test_ensemble": var_test_ensemble,
                     **{f"half_K{K}_M{M}": half_width(parts, K, M) for K, M in DESIGNS},
                     **decidable(parts, built[(better, worse)], var_test_ensemble, args.seeds)})
    return {"scene": scene, "rows": rows, "run_s_median": float(np.median(costs)), "test_train_ratio": ratio}


def table(result: dict) -> str:
    head = ("| ordering | mean diff (N) | sd split | sd seed | sd test | sd composition | "
            + " | ".join(f"±K{K} M{M}" for K, M in DESIGNS) + " |")
    lines = [f"### {result['scene']} ({args_text(result)})", "", head, "|" + "---|" * (6 + len(DESIGNS))]
    for r in result["rows"]:
        sd = [np.sqrt(r[k]) for k in ("var_split", "var_seed", "var_test", "var_composition")]
        lines.append(f"| {r['ordering']} | {r['mean']:+.3f} | " + " | ".join(f"{v:.3f}" for v in sd) + " | "
                     + " | ".join(f"{r[f'half_K{K}_M{M}']:.3f}" for K, M in DESIGNS) + " |")
    lines += ["", f"What any design of this data size decides, at the build's mean ({result['scene']}):", "",
              "| ordering | built: mean diff (N), verdict | room to decide (N) | sd test: one model / "
              "ensemble / shared | floor ± (endless repeats and seeds) | K, even odds: report's interval / "
              "seed share 1/K | K, 80 % power: one seed / ensembles |", "|---|---|---|---|---|---|---|"]
    for r in result["rows"]:
        k = {key: str(r[key]) if r[key] else "none" for key in ("K_report", "K_even", "K_80", "K_80_ensemble")}
        lines.append(f"| {r['ordering']} | {r['built_mean']:+.3f}, {r['built_verdict']} | {r['need']:.3f} | "
                     f"{np.sqrt(r['var_test']):.3f} / {np.sqrt(r['var_test_ensemble']):.3f} / "
                     f"{np.sqrt(r['var_test_shared']):.3f} | {r['floor']:.3f} | {k['K_report']} / {k['K_even']} | "
                     f"{k['K_80']} / {k['K_80_ensemble']} |")
    return "\n".join(lines)


def args_text(result: dict) -> str:
    r = result["rows"][0]
    return (f"{r['splits']} splits x {r['seeds']} seeds, n_test/n_train {result['test_train_ratio']:.2f}, "
            f"a run takes {result['run_s_median']:.0f} s (median)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build-dir", type=Path, default=REPO / "results" / "default", help="a built build's folder")
    ap.add_argument("--scale", default="default", help="the scale the build was made at")
    ap.add_argument("--scenes", nargs="+", default=["tool_normal", "tool_shear"], choices=sorted(ORDERINGS))
    ap.add_argument("--splits", type=int, default=3)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--jobs", type=int, default=2, help="training runs at once (one thread each)")
    ap.add_argument("--work-dir", type=Path, default=REPO / ".tactilepipe" / "study_noise")
    ap.add_argument("--out", type=Path, help="also write the numbers as JSON")
    args = ap.parse_args()
    if args.splits < 2 or args.seeds < 2:
        sys.exit("study_noise: --splits and --seeds must be at least 2 (a spread needs two draws)")
    t0 = time.perf_counter()
    with ThreadPoolExecutor(args.jobs) as pool:
        results = [study_scene(args, scene, pool) for scene in args.scenes]
    for result in results:
        print(table(result) + "\n")
    print(f"Standard deviations of the paired MAE difference (N); ±: the 95 % half-width under K repeated splits "
          f"with M model seeds each. Whole study: {time.perf_counter() - t0:.0f} s.")
    if args.out:
        write_json(args.out, {"results": results, "designs": DESIGNS})


if __name__ == "__main__":
    main()
