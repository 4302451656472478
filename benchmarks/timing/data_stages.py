"""Validated grasps per CPU-hour of the data stages (optimize -> curate -> lift-validate) of finished runs, as ratios.

    python benchmarks/timing/data_stages.py BASE_RUN RUN [RUN ...]

Each RUN is a workflow folder in which ``snakemake`` made ``results/lift/shard_*.zarr`` (e.g. the large profile's
slice: ``--configfile config/profiles/large.yaml overlay.yaml`` with ``objects: {builtin_count: 160}`` and
``shards: 2``, the versions run side by side with ``--cores 1`` each). CPU seconds come from the rules'
benchmark files (``logs/benchmarks/{optimize_grasps,curate,lift_validate}_*.tsv``); validated grasps are those
that held in ``results/lift``. Prints per run: the stages' CPU-s, optimized grasps, those passing the energy
thresholds, those stopped early, validated grasps, validated per CPU-hour and the ratio to the first run.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

STAGES = ("optimize_grasps", "curate", "lift_validate")


def stage_cpu_seconds(run: Path) -> dict[str, float]:
    """Stage -> CPU-s summed over its shards (the ``cpu_time`` column of snakemake's benchmark files)."""
    import pandas as pd

    totals = {}
    for stage in STAGES:
        files = sorted((run / "logs" / "benchmarks").glob(f"{stage}_[0-9]*.tsv"))
        if not files:
            raise SystemExit(f"data_stages.py: error: {run}: no logs/benchmarks/{stage}_*.tsv (has the run made results/lift?)")
        totals[stage] = float(sum(pd.read_csv(f, sep="\t")["cpu_time"].iloc[0] for f in files))
    return totals


def grasp_counts(run: Path) -> dict[str, int]:
    """Optimized, passing the energy thresholds, stopped early (where recorded) and lift-validated grasps."""
    from dexlite_pipeline.io.grasp_store import read_grasp_store

    optimized = [read_grasp_store(p) for p in sorted((run / "results" / "optimized").glob("shard_*.zarr"))]
    lifted = [read_grasp_store(p) for p in sorted((run / "results" / "lift").glob("shard_*.zarr"))]
    return {
        "optimized": sum(len(g) for g in optimized),
        "passing": sum(int(np.asarray(g.arrays["passes_energy_thresholds"], bool).sum()) for g in optimized),
        "stopped": sum(int((np.asarray(g.arrays["stopped_at_iteration"]) > 0).sum()) for g in optimized if "stopped_at_iteration" in g.arrays),
        "validated": sum(int(np.asarray(g.arrays["lift_success"], bool).sum()) for g in lifted),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=Path, nargs="+", help="the run before first, then the runs to compare with it")
    args = parser.parse_args(argv)
    print("| run | " + " | ".join(f"{s} CPU-s" for s in STAGES) + " | data stages CPU-s | optimized | passing | stopped early | validated "
          "| validated per CPU-hour | ratio |")
    print("| --- |" + " ---: |" * (len(STAGES) + 7))
    base_rate = None
    for run in args.runs:
        cpu, counts = stage_cpu_seconds(run), grasp_counts(run)
        total = sum(cpu.values())
        rate = counts["validated"] / total * 3600 if total else 0.0
        base_rate = rate if base_rate is None else base_rate
        print(f"| {run} | " + " | ".join(f"{cpu[s]:.1f}" for s in STAGES) + f" | {total:.1f} | {counts['optimized']} | {counts['passing']} | "
              f"{counts['stopped']} | {counts['validated']} | {rate:.0f} | {rate / base_rate if base_rate else float('nan'):.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
