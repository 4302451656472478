"""Check a finished run's held grasps against the tables of its objects' resting poses.

    python benchmarks/experiments/table_clearance.py results/

For every lift-validated and evaluated store of the run, per store: grasps, held grasps, and
held grasps with a hand point below the table (deeper than ``tabletop.TABLE_TOLERANCE_M``),
with the deepest. In tabletop mode the last count must be 0 (exit status 1 otherwise); in
floating mode it is the share of held grasps a table would forbid.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def main(argv: list[str] | None = None) -> int:
    from dexlite_pipeline.io.grasp_store import read_grasp_store
    from dexlite_pipeline.energy.table_clearance import grasp_table_depths
    from dexlite_pipeline.tabletop import TABLE_TOLERANCE_M, SupportPlanes

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", help="a run's results/ folder")
    parser.add_argument("--floating", action="store_true", help="the run was floating: report the share a table forbids, never fail")
    args = parser.parse_args(argv)
    results = Path(args.results)
    planes = SupportPlanes.from_stability_table(results / "stability" / "stability.parquet")
    stores = sorted((results / "lift").glob("shard_*.zarr")) + sorted((results / "eval" / "sim").glob("shard_*.zarr"))
    if not stores:
        print(f"{results}: no lift or evaluation stores", file=sys.stderr)
        return 2
    below_total = held_total = 0
    print("| store | method | grasps | held | held with a hand point below the table | deepest (mm) |")
    print("| --- | --- | ---: | ---: | ---: | ---: |")
    for path in stores:
        grasps = read_grasp_store(path)
        methods = np.asarray(grasps.arrays.get("method", np.full(len(grasps), "lift_validate", dtype=object))).astype(str)
        for method in sorted(set(methods)):
            mine = grasps.select(methods == method)
            held = mine.select(np.asarray(mine.arrays["lift_success"], bool))
            depth = grasp_table_depths(held, planes) if len(held) else np.zeros(0)
            below = int((~(depth <= TABLE_TOLERANCE_M)).sum())
            deepest = f"{1000 * np.nanmax(depth):.1f}" if below else "-"
            below_total += below
            held_total += len(held)
            print(f"| {path.parent.name}/{path.name} | {method} | {len(mine)} | {len(held)} | {below} | {deepest} |")
    share = below_total / held_total if held_total else float("nan")
    print(f"\nheld grasps: {held_total}; with a hand point below the table: {below_total} ({100 * share:.1f}%)")
    return 0 if args.floating or below_total == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
