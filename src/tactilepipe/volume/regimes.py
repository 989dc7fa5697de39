"""Table 1 of study 001 under each grasp regime of the simulator, next to the paper's values.

Each regime (params.yaml ``volume_regimes.regimes``: an overlay of the grasp keys of ``simulate_volume``)
records a whole simulated session and runs it through the same library functions as the volume
scene: bags -> shards -> off-table dataset -> folds -> MLP per modality -> mu-swept baseline.
Only the recordings differ between regimes; nothing downstream of the bags sees the regime.
Bags and shards go to a scratch folder inside ``out_dir`` that is removed after each regime; what
stays is the comparison (tables, figures, metrics.json) and each regime's per-lift QC
(``qc_<regime>.csv``): the mean off-table Fy and Fz of every lift and its Fz with the gripper closed
on the table before lift-off and after set-down (``grip_on_table``), the measurements that tell the
regimes apart.
"""

from __future__ import annotations

import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.core.atomic import write_json, write_text
from tactilepipe.core.errors import ConfigError
from tactilepipe.core.simulated import SIMULATED_PREFIX
from tactilepipe.papillarray.shards import ingest_bag
from tactilepipe.volume import simulate
from tactilepipe.volume.baseline import sweep
from tactilepipe.volume.dataset import build_dataset, off_table_segment, read_shard, session_lifts
from tactilepipe.volume.folds import make_folds
from tactilepipe.volume.mlp import MLPConfig
from tactilepipe.volume.report import _json_safe
from tactilepipe.volume.train import fit_modality

# Table 1 of "Force-based touch approach for volume estimation" ("Aproximación de tacto basada en
# fuerza para estimación de volumen"; two PapillArrays on a Robotiq 2F-140 and a UR5): R² mean ± std
# over its 5 test folds, and the mean mu of its baseline's per-fold optima.
PAPER_R2 = {"fz": (0.9842, 0.0049), "fy": (0.7651, 0.0195), "fy_fz": (0.9862, 0.0036),
            "fx_fy_fz": (0.9852, 0.0011), "baseline": (0.6817, 0.0122)}
PAPER_MU_STAR = 0.268
COLUMNS = ["fz", "fy", "fy_fz", "fx_fy_fz", "baseline"]
# The paper's ordering: Fz alone as good as {Fy,Fz} (within this R²), and both well above Fy.
SAME_R2, WELL_ABOVE_R2 = 0.02, 0.10


def _record_lift(job: tuple) -> None:
    bag, shard, lift, sim, seed = job
    simulate.write_lift_bag(bag, lift, sim, seed)
    ingest_bag(bag, shard)


def record_session(sim: dict, seed: int, raw_dir: Path, shard_dir: Path, jobs: int) -> None:
    """Simulate every lift of a session as a bag, with its lifts.csv, and ingest each to a shard."""
    plan = simulate.session_plan(sim)
    work = [(raw_dir / f"{l.name}.bag", shard_dir / f"{l.name}.parquet", l, sim, seed) for l in plan]
    if jobs <= 1:
        for job in work:
            _record_lift(job)
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            list(pool.map(_record_lift, work))
    simulate.write_session_labels(raw_dir, plan)


def grip_on_table(lifts: pd.DataFrame, seg: dict, window: dict, sensor: int) -> pd.DataFrame:
    """Mean Fz of ``sensor`` per lift in three phases: on the table with the gripper closed before
    lift-off (a window of ``window_s`` ending ``guard_s`` before the off-table phase), held off the
    table, and on the table after set-down (a window starting ``guard_s`` after the off-table phase);
    and the held Fy. Columns lift, fz_before_lift, fz_held, fz_after_place, fy_held (NaN when the
    recording does not reach a window)."""
    rows = []
    for row in lifts.itertuples(index=False):
        rec = read_shard(row.shard)
        start, stop, _ = off_table_segment(rec, seg, row.shard)
        t, fz, fy = rec["t"], rec[f"fz{sensor}"], rec[f"fy{sensor}"]
        t_up, t_down = t[start] - window["guard_s"], t[stop - 1] + window["guard_s"]
        before = (t >= t_up - window["window_s"]) & (t < t_up)
        after = (t > t_down) & (t <= t_down + window["window_s"])
        rows.append({"lift": row.lift,
                     "fz_before_lift": float(fz[before].mean()) if before.any() else float("nan"),
                     "fz_held": float(fz[start:stop].mean()), "fy_held": float(fy[start:stop].mean()),
                     "fz_after_place": float(fz[after].mean()) if after.any() else float("nan")})
    return pd.DataFrame(rows)


def analyse_session(p: dict, session: str, raw_root: Path, shard_root: Path) -> dict:
    """The volume scene's analysis of one session: R² per modality and of the baseline over the
    folds, mu*, and the per-lift QC table (with the on-table grip of ``grip_on_table``)."""
    lifts_table = session_lifts([session], raw_root, shard_root)
    data, qc = build_dataset(lifts_table, p["segment"], p["papillarray_axes"], p["volume_checks"])
    qc = qc.merge(grip_on_table(lifts_table, p["segment"], p["volume_regimes"]["on_table"], p["volume_sensor"]),
                  on="lift", how="left")
    lifts = data[["lift", "volume_ml", "set"]].drop_duplicates("lift")
    f = p["folds"]
    folds = make_folds(lifts, f["n_folds"], f["train_lifts_per_volume"], f["test_lifts_per_volume"],
                       p["seed"], source=session)
    cfg = MLPConfig.from_params(p["mlp"])
    r2 = {}
    for name, axes in p["mlp"]["modalities"].items():
        r2[name] = fit_modality(data, folds, axes, p["volume_sensor"], cfg, p["seed"])[1]["r2"].to_numpy()
    base = sweep(data, folds, p["volume_sensor"], p["baseline"])
    r2["baseline"] = base["summary"]["r2"].to_numpy()
    return {"r2": {m: {"mean": float(np.nanmean(v)), "std": float(np.nanstd(v)), "folds": v.tolist()}
                   for m, v in r2.items()},
            "mu_star": base["mu_star"], "mu_on_edge": base["on_edge"], "qc": qc}


def reproduces_ordering(r2: dict) -> bool:
    """Fz ≈ {Fy,Fz} ≫ Fy, as in the paper's Table 1."""
    fz, fy, both = r2["fz"]["mean"], r2["fy"]["mean"], r2["fy_fz"]["mean"]
    return bool(abs(fz - both) <= SAME_R2 and both - fy >= WELL_ABOVE_R2 and fz - fy >= WELL_ABOVE_R2)


def compare_regimes(p: dict, out_dir: Path, jobs: int = 1, only: list[str] | None = None) -> dict:
    """Run every regime of ``p["volume_regimes"]`` (or ``only`` these) and write the comparison."""
    regimes = p["volume_regimes"]["regimes"]
    names = list(only) if only else list(regimes)
    unknown = [n for n in names if n not in regimes]
    if unknown:
        raise ConfigError(f"--regimes: {unknown} not in params.yaml volume_regimes.regimes ({sorted(regimes)})")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    results = {}
    for name in names:
        sim = {**p["simulate_volume"], **regimes[name]}
        session = SIMULATED_PREFIX + name
        # a default-scale session is ~0.4 GB of bags: one regime's scratch at a time
        with tempfile.TemporaryDirectory(prefix=".scratch-", dir=out_dir) as scratch:
            raw_root, shard_root = Path(scratch) / "raw", Path(scratch) / "shards"
            record_session(sim, p["seed"], raw_root / session, shard_root / session, jobs)
            results[name] = analyse_session(p, session, raw_root, shard_root)
    for name, res in results.items():
        write_text(out_dir / f"qc_{name}.csv", res["qc"].to_csv(index=False))
    return write_comparison(results, {n: regimes[n] for n in names}, p, out_dir)


def _cell(mean: float, std: float) -> str:
    return "undefined" if not np.isfinite(mean) else f"{mean:.3f} ± {std:.3f}"


def write_comparison(results: dict, overlays: dict, p: dict, out_dir: Path) -> dict:
    """table1_regimes.{csv,md}, fz_vs_volume.{csv,md}, figures and metrics.json from the results."""
    from tactilepipe.volume import figures_regimes
    rows = []
    for name, res in results.items():
        row = {"regime": name, "overlay": _overlay_text(overlays[name])}
        for m in COLUMNS:
            row[f"{m}_mean"], row[f"{m}_std"] = res["r2"][m]["mean"], res["r2"][m]["std"]
        row.update(mu_star=res["mu_star"], paper_ordering=reproduces_ordering(res["r2"]))
        rows.append(row)
    paper = {"regime": "paper", "overlay": "real rig (Table 1)", "mu_star": PAPER_MU_STAR,
             **{f"{m}_{k}": PAPER_R2[m][i] for m in COLUMNS for i, k in enumerate(("mean", "std"))}}
    paper["paper_ordering"] = reproduces_ordering({m: {"mean": PAPER_R2[m][0]} for m in COLUMNS})
    table = pd.DataFrame(rows + [paper])
    write_text(out_dir / "table1_regimes.csv", table.to_csv(index=False))
    head = ["regime", "grasp (simulate_volume overlay)", "Fz", "Fy", "{Fy,Fz}", "{Fx,Fy,Fz}",
            "est_vol baseline", "μ*", "Fz ≈ {Fy,Fz} ≫ Fy"]
    lines = [f"**Table 1 by grasp regime: R² on test lifts, mean ± std over {p['folds']['n_folds']} folds "
             f"(scale {p['scale']}, seed {p['seed']})**", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in table.to_dict("records"):
        cells = [r["regime"], r["overlay"]] + [_cell(r[f"{m}_mean"], r[f"{m}_std"]) for m in COLUMNS]
        cells += [f"{r['mu_star']:.3f}" if np.isfinite(r["mu_star"]) else "undefined",
                  "yes" if r["paper_ordering"] else "no"]
        lines.append("| " + " | ".join(cells) + " |")
    write_text(out_dir / "table1_regimes.md", "\n".join(lines) + "\n")

    grip = pd.concat([res["qc"][res["qc"]["set"] == "main"].assign(regime=name) for name, res in results.items()])
    cols = {"fz_before_lift": "fz_before", "fz_held": "fz", "fz_after_place": "fz_after", "fy_held": "fy"}
    by_volume = grip.groupby(["regime", "volume_ml"], sort=False)[list(cols)].agg(["mean", "std"]).reset_index()
    by_volume.columns = ["regime", "volume_ml"] + [f"{cols[c]}_{k}_n" for c in cols for k in ("mean", "std")]
    write_text(out_dir / "fz_vs_volume.csv", by_volume.to_csv(index=False))
    sensor = p["volume_sensor"]
    vol_lines = [f"**Sensor {sensor} per lift, by volume (mean ± std over lifts, N): Fz on the table before "
                 f"lift-off, Fz and Fy held off the table, Fz on the table after set-down**", "",
                 "| regime | volume (ml) | Fz before lift-off | Fz held | Fz after set-down | Fy held |",
                 "|---|---|---|---|---|---|"]
    for r in by_volume.to_dict("records"):
        cells = [f"{r[f'{c}_mean_n']:.3f} ± {r[f'{c}_std_n']:.3f}" for c in ("fz_before", "fz", "fz_after", "fy")]
        vol_lines.append(f"| {r['regime']} | {r['volume_ml']:g} | " + " | ".join(cells) + " |")
    write_text(out_dir / "fz_vs_volume.md", "\n".join(vol_lines) + "\n")

    figures_regimes.r2_by_regime(table, COLUMNS, out_dir / "figures" / "r2_by_regime.png")
    figures_regimes.fz_vs_volume(grip, p["volume_sensor"], out_dir / "figures" / "fz_vs_volume.png")
    metrics = {"scale": p["scale"], "seed": p["seed"], "paper": {"r2": {m: {"mean": v[0], "std": v[1]}
                                                                        for m, v in PAPER_R2.items()},
                                                                 "mu_star": PAPER_MU_STAR},
               "regimes": {name: {"overlay": overlays[name], "r2": res["r2"], "mu_star": res["mu_star"],
                                  "mu_optimum_on_edge": res["mu_on_edge"],
                                  "paper_ordering": reproduces_ordering(res["r2"])}
                           for name, res in results.items()}}
    write_json(out_dir / "metrics.json", _json_safe(metrics))
    return metrics


def _overlay_text(overlay: dict) -> str:
    return ", ".join(f"{k}={v}" for k, v in overlay.items()) or "params.yaml as is"
