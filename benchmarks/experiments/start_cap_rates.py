"""Held per attempt under start caps of 1, 2, 3, 5 and 10 mm, from one simulation of a run's evaluated grasps.

    python benchmarks/experiments/start_cap_rates.py RESULTS_DIR [--threads 2] [--out rates.csv]

The lift test's start check refuses a grasp before simulating it; what happens after does not
depend on the cap. So every grasp under ``RESULTS_DIR/eval/sim/`` is lift-tested once (no
six-direction test) with the cap at 10 mm and the run's other lift settings, and a grasp holds
under cap c when it lifted and its start depth (the judged penetration depth) is at most c.
Prints per method and split the held share per attempt at each cap with a 95% Wilson interval at
2 mm, and the held grasps' start depth (median / p90). About 0.1 s per grasp and core.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

CAPS_MM = (1.0, 2.0, 3.0, 5.0, 10.0)


def main() -> None:
    import pandas as pd

    from dexlite_pipeline.evaluation.rates import wilson_interval
    from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store
    from dexlite_pipeline.sim.config import LiftConfig
    from dexlite_pipeline.sim.lift import run_lift_tests
    from dexlite_pipeline.tabletop import load_support_planes

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", type=Path)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    sim = args.results / "eval" / "sim"
    stores = [read_grasp_store(p) for p in sorted(sim.glob("shard_*.zarr"))]
    if not stores:
        raise SystemExit(f"{sim}: no evaluation shards (run the pipeline first)")
    names = ("hand_pose", "object_id", "scale", "method", "split")
    grasps = GraspSet({n: np.concatenate([np.asarray(s.arrays[n]) for s in stores]) for n in names})
    record = json.loads((args.results / "eval" / "evaluation.json").read_text())
    lift = dataclasses.replace(LiftConfig(**record["lift_config"]), max_initial_penetration_m=0.01, six_directions=False)
    table = all("support_normal" in store.arrays for store in stores)  # tabletop runs record each grasp's table
    planes = load_support_planes(table, args.results / "stability" / "stability.parquet")
    result = run_lift_tests(grasps, [args.results / "objects", sim], lift, args.threads, planes)
    depth = np.asarray(result["initial_penetration_mm"], np.float64)
    lifted = np.asarray(result["lift_success"], bool)
    rows = []
    frame = pd.DataFrame({"method": grasps.arrays["method"].astype(str), "split": grasps.arrays["split"].astype(str)})
    for (method, split), part in frame.groupby(["method", "split"], sort=False):
        index = part.index.to_numpy()
        row = {"method": method, "split": split, "attempts": len(index)}
        for cap in CAPS_MM:
            row[f"held_at_{cap:g}mm"] = float(np.mean(lifted[index] & (depth[index] <= cap)))
        low, high = wilson_interval(lifted[index] & (depth[index] <= 2.0))
        row["held_at_2mm_ci95"] = f"{100 * low:.1f}–{100 * high:.1f}%"
        held_depth = depth[index][lifted[index] & np.isfinite(depth[index])]
        row["held_start_depth_median_mm"] = float(np.median(held_depth)) if len(held_depth) else np.nan
        row["held_start_depth_p90_mm"] = float(np.percentile(held_depth, 90)) if len(held_depth) else np.nan
        rows.append(row)
    out = pd.DataFrame(rows)
    with pd.option_context("display.width", 200, "display.max_columns", 20, "display.float_format", "{:.3f}".format):
        print(out.to_string(index=False))
    if args.out:
        out.to_csv(args.out, index=False)


if __name__ == "__main__":
    main()
