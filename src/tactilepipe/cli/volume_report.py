"""Stage of the volume study: its scores, metrics, tables and figures."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.cli.volume_args import VOLUME_CHECKS


@command("volume-report", "scores.json, metrics/, tables and figures of the volume study",
         checks=VOLUME_CHECKS,
         params=("scale", "volume_sessions", "mlp.modalities", "mlp.grid.modality", "mlp.grid.inner_folds",
                 "folds.train_lifts_per_volume", "folds.test_lifts_per_volume"),
         args=(arg("--in-dir", required=True, help="the scene's results folder"),
               arg("--raw-root", default="raw/volume"), arg("--shard-root", default="results/default/volume/shards")),
         provenance=True)
def cmd_volume_report(args, p) -> None:
    from tactilepipe.volume.report import build_report
    build_report(Path(args.in_dir), p, Path(args.raw_root), Path(args.shard_root))
    from tactilepipe.cli.provenance import write_scene_provenance
    write_scene_provenance(args, Path(args.in_dir))
