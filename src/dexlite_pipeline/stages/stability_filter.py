"""``dexlite stability-filter --config-json JSON --objects DIR --out stability.parquet``: PyBullet table test.

Config sections ``seed`` and ``stability``. Every object of each ``--objects`` catalog gets a
row (object_id, lateral_displacement_m, rotation_deg, stable, reason): ok objects are
simulated in parallel, rejected ones are carried with their rejection reason. The config
used is written next to the table (``<out stem>_config.json``). Catalogs without a single
prepared (ok) object are an error (exit status 1, nothing written).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import os
import time
from pathlib import Path

log = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", default="{}", help="config sections seed and stability as JSON (defaults otherwise)")
    parser.add_argument("--objects", action="append", required=True, help="objects dir with catalog.parquet and assets/ (repeatable)")
    parser.add_argument("--out", required=True, help="output table (.parquet)")


def config_record_path(out: str | Path) -> Path:
    out = Path(out)
    return out.with_name(f"{out.stem}_config.json")


def run(args: argparse.Namespace) -> int:
    import pandas as pd

    from dexlite_pipeline.config import from_section, parse_config_json
    from dexlite_pipeline.io.atomic import atomic_path
    from dexlite_pipeline.objects.assets import read_catalog
    from dexlite_pipeline.objects.stability import StabilityConfig, stability_table

    config = parse_config_json(args.config_json)
    seed = int(config.get("seed", 0))
    section = from_section(StabilityConfig, config.get("stability"), "config.stability")
    catalog = pd.concat([read_catalog(d) for d in args.objects], ignore_index=True).drop_duplicates("object_id", keep="first")
    if not (catalog["status"] == "ok").any():
        log.error("%s: no prepared object to test (%d in the catalogs, all rejected)", ", ".join(args.objects), len(catalog))
        return 1
    workers = args.threads or os.cpu_count() or 1
    start = time.perf_counter()
    table = stability_table(catalog, args.objects, section, seed, workers)
    elapsed = time.perf_counter() - start
    with atomic_path(config_record_path(args.out)) as tmp:
        tmp.write_text(json.dumps({"seed": seed, "stability": dataclasses.asdict(section), "objects": args.objects}, indent=2, sort_keys=True))
    with atomic_path(args.out) as tmp:
        table.to_parquet(tmp, index=False)
    simulated = int((catalog["status"] == "ok").sum())
    for row in table[~table["stable"]].itertuples():
        log.info("not stable %s: %s", row.object_id, row.reason)
    print(
        f"{int(table['stable'].sum())}/{simulated} simulated objects stable ({len(table) - simulated} rejected earlier), "
        f"{elapsed:.1f} s ({simulated / max(elapsed, 1e-9):.1f} objects/s) -> {args.out}"
    )
    return 0
