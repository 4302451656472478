"""Command-line options the data loop's per-shard stages share (``loop_sample``, ``loop_post_optimize``, ``loop_validate``):
one round's step on one part (training or held-out objects) of one shard."""

from __future__ import annotations

import argparse

from dexlite_pipeline.loop.round_basics import PARTS


def add_round_shard_arguments(parser: argparse.ArgumentParser, config_sections: str, out_help: str) -> None:
    """The options every per-shard loop stage takes besides its input store: ``--config-json`` (``config_sections``
    named in its help), ``--stability``, ``--objects``, ``--round``, ``--part``, ``--shard`` and ``--out``."""
    parser.add_argument("--config-json", required=True, help=f"config sections {config_sections} (JSON)")
    parser.add_argument("--stability", required=True, help="stability.parquet of the stability_filter stage (stable objects; resting poses in tabletop mode)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir with catalog.parquet (repeatable)")
    parser.add_argument("--round", required=True, type=int, help="the loop round, 0, 1, ...")
    parser.add_argument("--part", required=True, choices=PARTS, help="the objects sampled on: training or held-out")
    parser.add_argument("--shard", required=True, type=int, help="shard number, e.g. 000")
    parser.add_argument("--out", required=True, help=out_help)
