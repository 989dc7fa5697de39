"""Stage of the volume and drift studies: PapillArray bags into Parquet shards."""

from __future__ import annotations

import json

from tactilepipe.cli.registry import arg, command
from tactilepipe.core.errors import TactilepipeError
from tactilepipe.papillarray.checks import check as papillarray_check


@command("papillarray-ingest", "PapillArray bag(s) -> Parquet shard(s) (the volume and drift studies)",
         checks=(papillarray_check,),
         params=("papillarray_ingest",),
         args=(arg("bags", nargs="+", metavar="BAG SHARD", help="pairs: input bag, output shard"),))
def cmd_papillarray_ingest(args, p) -> None:
    from tactilepipe.papillarray.shards import ingest_bag
    if len(args.bags) % 2:
        raise TactilepipeError(f"papillarray-ingest takes BAG SHARD pairs; got {len(args.bags)} paths "
                               f"(the last, {args.bags[-1]}, has no shard)")
    for bag, shard in zip(args.bags[0::2], args.bags[1::2]):
        info = ingest_bag(bag, shard, max_span_offset_s=p["papillarray_ingest"]["max_span_offset_s"])
        print(json.dumps(info))
