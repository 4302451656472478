"""Stage ``loop_table``: results/loop.csv, one row per round of the data loop (the report's "Data loop" section)."""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--row", action="append", required=True, help="a round's row (loop_summary's .json; repeatable)")
    parser.add_argument("--out", required=True, help="output loop table (.csv)")


def run(args: argparse.Namespace) -> int:
    import json
    from pathlib import Path

    from dexlite_pipeline.atomic import atomic_path
    from dexlite_pipeline.loop.table import loop_table

    table = loop_table([json.loads(Path(p).read_text()) for p in args.row])
    with atomic_path(args.out) as tmp:
        table.to_csv(tmp, index=False)
    return 0
