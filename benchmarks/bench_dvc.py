"""DVC + Snakemake overhead at the default scale, in a temporary git + DVC copy of the project:

- no-op `snakemake --cores 2` and no-op `dvc repro` (everything built; target <= 5 s each),
- taking in one new volume session (`dvc add` + `dvc repro`) against a full rebuild of the volume
  scene from the same recordings (both sessions, every bag re-ingested).

The default-scale recordings, shards and tool models of this checkout are reused when present
(recordings hard-linked: nothing here writes them in place; shards, tool results and Snakemake's
.snakemake/metadata copied with their mtimes, so Snakemake finds them up to date), else simulated
and trained (about 45 min for the tool models on 2 cores). The stages timed are simulate_*,
volume, drift, tool_data and tool_models.

    .venv/bin/python benchmarks/bench_dvc.py [--keep] [--small]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
ENV = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"}
STAGES = ["volume", "drift", "tool_data", "tool_models"]       # + their upstream simulate_* stages
SMK_TARGETS: list[str] = []                                      # `all`: every scene of params.yaml
NEW = "s-bench"
TARGET_S = 5.0


def sh(cmd: list[str], cwd: Path) -> float:
    t0 = time.perf_counter()
    # the copy runs its own source: its files are what the rules and dvc.yaml list as code deps
    env = {**ENV, "PYTHONPATH": str(cwd / "src")} if (cwd / "src" / "tactilepipe").is_dir() else ENV
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return dt


def setup(wd: Path, small: bool = False) -> float:
    for name in ("Snakefile", "params.yaml", "dvc.yaml", ".dvcignore", ".gitignore"):
        shutil.copy(REPO / name, wd / name)
    if small:                                                  # the smoke scale's drift scene only
        text = (wd / "params.yaml").read_text()
        assert "scale: default " in text
        (wd / "params.yaml").write_text(text.replace("scale: default ", "scale: smoke ", 1))
    for name in ("workflow", "src"):
        shutil.copytree(REPO / name, wd / name, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    (wd / "profiles").symlink_to("workflow/profiles")      # plain `snakemake` finds profiles/default
    for scene in () if small else ("volume", "drift", "tool"):
        src = REPO / "raw" / scene / "sim-default"
        if src.is_dir():
            (wd / "raw" / scene).mkdir(parents=True, exist_ok=True)
            subprocess.run(["cp", "-al", str(src), str(wd / "raw" / scene)], check=True)
    for shards in ("volume/shards/sim-default", "drift/shards/sim-default", "tool/shards/sim-default"):
        if not small and (REPO / "results/default" / shards).is_dir():
            shutil.copytree(REPO / "results/default" / shards, wd / "results/default" / shards)     # keeps mtimes
    for scene in ("tool_normal", "tool_shear"):                       # data, splits, models, figures
        if not small and (REPO / "results/default" / scene / "scores.json").is_file():
            shutil.copytree(REPO / "results/default" / scene, wd / "results/default" / scene,
                            ignore=shutil.ignore_patterns("last.pt"))
    # the rules' parameter stamps, with their times (older than the results they made)
    if not small and (REPO / "results/default/params").is_dir():
        shutil.copytree(REPO / "results/default/params", wd / "results/default/params")
    # Snakemake's records of how each output was made (rule, params, input checksums): without
    # them the copy is a fresh clone, and the outputs DVC re-copies from its cache while committing
    # tool_data (new mtimes) would look newer than the models and re-train them (`make pull`
    # marks pulled results current for the same reason)
    if not small and (REPO / ".snakemake/metadata").is_dir():
        shutil.copytree(REPO / ".snakemake/metadata", wd / ".snakemake/metadata")
    sh(["git", "init", "-q"], wd)
    sh(["git", "config", "user.email", "bench@example.com"], wd)
    sh(["git", "config", "user.name", "bench"], wd)
    sh([str(BIN / "dvc"), "init", "-q"], wd)
    shutil.copy(REPO / ".dvc/config", wd / ".dvc/config")
    sh([str(BIN / "dvc"), "remote", "modify", "local", "url", str(wd.parent / "remote")], wd)
    dt = sh([str(BIN / "dvc"), "repro", *(["drift"] if small else STAGES)], wd)
    sh(["git", "add", "."], wd)
    sh(["git", "commit", "-q", "-m", "default scale"], wd)
    return dt


def best_of(cmd: list[str], wd: Path, n: int = 3) -> tuple[float, float]:
    times = [sh(cmd, wd) for _ in range(n)]
    return min(times), statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", action="store_true", help="keep the temporary project")
    ap.add_argument("--small", action="store_true", help="the drift scene at the smoke scale, each command once, "
                    "no new session: a check that it runs")
    args = ap.parse_args()
    stages, repeats = (["drift"], 1) if args.small else (STAGES, 3)
    root = Path(tempfile.mkdtemp(prefix="bench_dvc_"))
    wd = root / "project"
    wd.mkdir()
    try:
        print(f"project copy in {wd}; building the {'smoke' if args.small else 'default'} scale once "
              f"(dvc repro {' '.join(stages)}) ...", flush=True)
        print(f"  first dvc repro (reused recordings and shards): {setup(wd, args.small):.1f} s", flush=True)
        targets = ["results/smoke/drift/metrics/loaded.json"] if args.small else SMK_TARGETS
        smk_first = sh([str(BIN / "snakemake"), "--cores", "2", "-n", *targets], wd)
        smk = best_of([str(BIN / "snakemake"), "--cores", "2", *targets], wd, repeats)
        rep = best_of([str(BIN / "dvc"), "repro", *stages], wd, repeats)
        if args.small:
            print("\n| measurement (smoke scale, drift scene) | wall time |\n|---|---|")
            print(f"| no-op `snakemake` | {smk[0]:.2f} s |\n| first `snakemake -n` after `dvc repro` | {smk_first:.2f} s |")
            print(f"| no-op `dvc repro drift` | {rep[0]:.2f} s |")
            return

        rig = root / "rig" / NEW
        t0 = time.perf_counter()
        sh([str(BIN / "tactilepipe"), "volume-simulate", "--override", '{"seed": 7}', "--out-dir", str(rig),
            "--labels", "--jobs", "2"], wd)
        t_record = time.perf_counter() - t0
        shutil.copytree(rig, wd / "raw/volume" / NEW)
        n_bags = len(list(rig.glob("*.bag")))
        params = (wd / "params.yaml").read_text()
        (wd / "params.yaml").write_text(params.replace('volume_sessions: ["sim-{scale}"]',
                                                       f'volume_sessions: ["sim-{{scale}}", "{NEW}"]'))
        t_add = sh([str(BIN / "dvc"), "add", f"raw/volume/{NEW}"], wd)
        t_new = sh([str(BIN / "dvc"), "repro", *STAGES], wd)
        n_shards = len(list((wd / "results/default/volume/shards" / NEW).glob("*.parquet")))
        assert n_shards == n_bags, f"the new session was not taken in ({n_shards} of {n_bags} shards)"
        shutil.rmtree(wd / "results/default/volume/shards")
        t_full = sh([str(BIN / "dvc"), "repro", "--force", "--single-item", "volume"], wd)

        print("\n| measurement (default scale, 2 cores) | wall time | target |")
        print("|---|---|---|")
        print(f"| no-op `{' '.join(['snakemake', '--cores', '2', *SMK_TARGETS])}` | {smk[0]:.2f} s (median {smk[1]:.2f}) "
              f"| <= {TARGET_S:.0f} s {'ok' if smk[0] <= TARGET_S else 'MISSED'} |")
        print(f"| first `snakemake -n` right after `dvc repro` (DVC re-copied the outputs) | {smk_first:.2f} s | |")
        print(f"| no-op `dvc repro {' '.join(STAGES)}` | {rep[0]:.2f} s (median {rep[1]:.2f}) "
              f"| <= {TARGET_S:.0f} s {'ok' if rep[0] <= TARGET_S else 'MISSED'} |")
        print(f"| new volume session ({n_bags} bags): `dvc add` | {t_add:.1f} s | |")
        print(f"| new volume session: `dvc repro` (ingest {n_bags} new bags, rebuild the scene) | {t_new:.1f} s | |")
        print(f"| full rebuild of the volume scene, both sessions (`dvc repro -f -s volume`, "
              f"shards removed) | {t_full:.1f} s | |")
        print(f"| new session / full rebuild | {(t_add + t_new) / t_full:.0%} | |")
        print(f"(recording the new session with the simulator took {t_record:.1f} s, not counted)")
    finally:
        if args.keep:
            print(f"kept {root}")
        else:
            shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
