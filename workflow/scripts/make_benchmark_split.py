"""Draw the fixed benchmark split: procedural pybullet_data objects that are always held out.

    python workflow/scripts/make_benchmark_split.py --count 48 --out src/dexlite_pipeline/objects/benchmark_split.yaml

Candidates are the procedural objects (``random_urdfs``) that the default run does not draw for
seeds 0-2 (so the default run keeps its own split and published numbers). They are taken in a
seeded random order; each is prepared with the default ``objects`` settings and put through the
default table-stability test; the first ``--count`` that are prepared and stable form the
split. The result records the rule, the seed and the candidates that were passed over, with why.
"""

from __future__ import annotations

import argparse
import datetime
import tempfile
from pathlib import Path

import numpy as np
import yaml

from dexlite_pipeline.objects.config import ObjectsConfig
from dexlite_pipeline.objects.prepare import prepare_objects
from dexlite_pipeline.objects.sources import builtin_sources, pybullet_random_source, random_pybullet_paths
from dexlite_pipeline.objects.config import StabilityConfig
from dexlite_pipeline.objects.stability import stability_table

SPLIT_SEED = 20261201
DEFAULT_RUN_SEEDS = (0, 1, 2)
DEFAULT_BUILTIN_COUNT = 40


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=48, help="benchmark objects wanted")
    parser.add_argument("--candidates", type=int, default=96, help="candidates prepared and tested, in seeded order")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", required=True)
    args = parser.parse_args()

    used_by_default = {s.object_id for seed in DEFAULT_RUN_SEEDS for s in builtin_sources(DEFAULT_BUILTIN_COUNT, seed)}
    paths = [p for p in random_pybullet_paths() if f"pb-random-{p.stem}" not in used_by_default]
    order = np.random.default_rng(SPLIT_SEED).permutation(len(paths))[: args.candidates]
    sources = [pybullet_random_source(paths[i]) for i in order]
    with tempfile.TemporaryDirectory() as tmp:
        catalog = prepare_objects(sources, Path(tmp), ObjectsConfig(), seed=0, workers=args.workers)
        table = stability_table(catalog, [tmp], StabilityConfig(), seed=0, workers=args.workers).set_index("object_id")
    chosen, passed_over = [], {}
    for source in sources:
        oid = source.object_id
        row = catalog.loc[catalog["object_id"] == oid].iloc[0]
        if row["status"] != "ok":
            passed_over[oid] = f"not prepared: {row['reason']}"
        elif not bool(table.loc[oid, "stable"]):
            passed_over[oid] = f"not stable: {table.loc[oid, 'reason']}"
        elif len(chosen) < args.count:
            chosen.append(oid)
        if len(chosen) == args.count:
            break
    if len(chosen) < args.count:
        raise SystemExit(f"only {len(chosen)} of {args.count} benchmark objects found among {len(sources)} candidates; raise --candidates")
    record = {
        "description": "Benchmark split: procedural pybullet_data objects that every profile holds out (never trained on).",
        "rule": (f"procedural objects not drawn by the default run (builtin_count {DEFAULT_BUILTIN_COUNT}, seeds "
                 f"{list(DEFAULT_RUN_SEEDS)}), in the order of numpy default_rng({SPLIT_SEED}).permutation; the first "
                 f"{args.count} prepared and table-stable with the default settings"),
        "made_by": "workflow/scripts/make_benchmark_split.py",
        "made_on": datetime.date.today().isoformat(),
        "object_ids": chosen,
        "passed_over": passed_over,
    }
    Path(args.out).write_text(yaml.safe_dump(record, sort_keys=False, width=120))
    print(f"{len(chosen)} benchmark objects ({len(passed_over)} candidates passed over) -> {args.out}")


if __name__ == "__main__":
    main()
