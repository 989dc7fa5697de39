"""Stage of the volume study: the off-table phase of every lift, checked, in one table."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.cli.volume_args import VOLUME_CHECKS


@command("volume-dataset", "segment the off-table phase of every lift",
         checks=VOLUME_CHECKS,
         params=("volume_sessions", "segment", "papillarray_axes", "volume_checks"),
         args=(arg("--raw-root", default="raw/volume"), arg("--shard-root", default="results/default/volume/shards"),
               arg("--out", required=True), arg("--qc", required=True)))
def cmd_volume_dataset(args, p) -> None:
    from tactilepipe.core.atomic import write_parquet, write_text
    from tactilepipe.volume.dataset import build_dataset, session_lifts
    lifts = session_lifts(p["volume_sessions"], Path(args.raw_root), Path(args.shard_root))
    data, qc = build_dataset(lifts, p["segment"], p["papillarray_axes"], p["volume_checks"])
    write_parquet(args.out, data)
    write_text(args.qc, qc.to_csv(index=False))
