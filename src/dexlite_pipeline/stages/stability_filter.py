"""``dexlite stability-filter --objects DIR --out stability.parquet --record ...``: PyBullet table test.

Config sections ``seed`` and ``stability``. Every object of each ``--objects`` catalog gets a
row (object_id, lateral_displacement_m, rotation_deg, stable, reason): ok objects are
simulated in parallel, rejected ones are carried with their rejection reason
(``objects.stability.stability_filter``). The config used is written to ``--record``.
Catalogs without a single prepared (ok) object are an error (exit status 1, nothing written).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import time

log = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", default="{}", help="config sections seed and stability as JSON (defaults otherwise)")
    parser.add_argument("--objects", action="append", required=True, help="objects dir with catalog.parquet and assets/ (repeatable)")
    parser.add_argument("--out", required=True, help="output table (.parquet)")
    parser.add_argument("--record", required=True, help="output record of the settings used (.json)")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.config import json_ready
    from dexlite_pipeline.atomic import atomic_path
    from dexlite_pipeline.objects.stability import NoObjectToTest, stability_filter
    from dexlite_pipeline.settings import stage_config

    config = stage_config(args.config_json)
    start = time.perf_counter()
    try:
        table = stability_filter(args.objects, config.seed, config.stability, args.threads or os.cpu_count() or 1)
    except NoObjectToTest as exc:
        log.error("%s", exc)
        return 1
    elapsed = time.perf_counter() - start
    with atomic_path(args.record) as tmp:
        tmp.write_text(json.dumps({"seed": config.seed, "stability": json_ready(config.stability), "objects": args.objects}, indent=2, sort_keys=True))
    with atomic_path(args.out) as tmp:
        table.to_parquet(tmp, index=False)
    for row in table[~table["stable"]].itertuples():
        log.info("not stable %s: %s", row.object_id, row.reason)
    print(f"{int(table['stable'].sum())}/{len(table)} objects stable, {elapsed:.1f} s ({len(table) / max(elapsed, 1e-9):.1f} objects/s) -> {args.out}")
    return 0
