"""Held-out results per object split (household, shapes and benchmark splits) over runs that differ in their seed.

    python benchmarks/experiments/split_table.py RUN [RUN ...] [--methods cvae_post cvae_ranked_post optimization ...] [--wall-to-cpu]
        [--families]

Each RUN is a finished run folder (``results/eval/metrics.csv``, ``per_object.csv``, ``results/objects/catalog.parquet``),
e.g. the household model's profile at training seeds 0, 1, 2 (``train.seed``). Prints a Markdown table per split: per
method and run, held per attempt (Wilson 95%), six-direction success, distinct held grasps per object and CPU-seconds per
distinct held grasp (``dexlite_pipeline.evaluation.subsets``), and the runs pooled (attempts and grasps summed); then per
split and run the learned evaluator's ROC AUC for "held" (its score of each sampled pose against the outcome of the refined
grasp, ``cvae_post``'s attempts). ``--wall-to-cpu``: for runs made before the stages counted process CPU seconds, each
stage's seconds per attempt are scaled by its jobs' CPU time over wall time (Snakemake's benchmark files). ``--families``:
one table per family of the held-out objects instead of per split (``evaluation.subsets.family_subsets``), with the share
of objects holding at least 4 distinct grasps.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pandas as pd

from dexlite_pipeline.evaluation.ranking import roc_auc
from dexlite_pipeline.evaluation.rates import wilson_interval
from dexlite_pipeline.evaluation.subsets import run_split_rows, split_subsets

METHODS = ("cvae_ranked_post", "cvae_post", "optimization", "random_post", "shipped_post", "cvae_ranked", "cvae_raw", "shipped_raw")


def evaluator_auc(run: Path, subsets: dict[str, list[str]]) -> dict[str, float]:
    """Split -> ROC AUC of the evaluator's score of each unranked sample for its refined grasp's "held" (cvae_post rows)."""
    from dexlite_pipeline.io.grasp_store import read_grasp_store

    stores = [read_grasp_store(path) for path in sorted((run / "results" / "eval" / "sim").glob("shard_*.zarr"))]
    rows = [(s.object_id[i], float(s.arrays["evaluator_score"][i]), bool(s.arrays["lift_success"][i]))
            for s in stores if "evaluator_score" in s.arrays for i in np.flatnonzero(s.arrays["method"].astype(str) == "cvae_post")]
    table = pd.DataFrame(rows, columns=["object_id", "score", "held"]).astype({"score": float, "held": bool})  # empty: no evaluator
    return {name: roc_auc(part["score"].to_numpy(), part["held"].to_numpy())
            for name, ids in subsets.items() if len(part := table[table.object_id.isin(ids) & np.isfinite(table.score)])}


def pooled(rows: pd.DataFrame) -> dict:
    attempts, held = int(rows["attempts"].sum()), int(rows["held"].sum())
    low, high = wilson_interval(np.arange(attempts) < held)
    distinct = (rows["distinct_held_per_object"] * rows["objects"]).sum()
    seconds = (rows["cpu_seconds_per_distinct_held"] * rows["distinct_held_per_object"] * rows["objects"]).sum()
    share = (rows["objects_with_min_distinct"] * rows["objects"]).sum() / rows["objects"].sum()
    return {"run": "pooled", "attempts": attempts, "objects_with_min_distinct": share, "held": held, "held_rate": held / attempts, "held_ci95_low": low, "held_ci95_high": high,
            "six_dir_rate": (rows["six_dir_rate"] * rows["attempts"]).sum() / attempts,
            "distinct_held_per_object": distinct / rows["objects"].sum(), "cpu_seconds_per_distinct_held": seconds / distinct if distinct else math.nan}  # fmt: skip


def markdown(table: pd.DataFrame) -> str:
    lines = []
    for subset, part in table.groupby("subset", sort=False):
        lines += [f"### {subset}", "", "| method | run | attempts | held per attempt | six directions | distinct held / object | CPU-s / distinct held "
                  "| objects with >= 4 distinct held |", "| --- | --- | ---: | --- | ---: | ---: | ---: | ---: |"]  # fmt: skip
        for method, rows in part.groupby("method", sort=False):
            entries = [r._asdict() for r in rows.itertuples(index=False)]
            if len(rows) > 1:
                entries.append(pooled(rows))
            for r in entries:
                lines.append(f"| {method} | {r['run']} | {r['attempts']} | {100 * r['held_rate']:.1f}% ({100 * r['held_ci95_low']:.1f}–"
                             f"{100 * r['held_ci95_high']:.1f}) | {100 * r['six_dir_rate']:.1f}% | {r['distinct_held_per_object']:.2f} | "
                             f"{r['cpu_seconds_per_distinct_held']:.3f} | {100 * r.get('objects_with_min_distinct', math.nan):.0f}% |")  # fmt: skip
        lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--methods", nargs="+", default=list(METHODS))
    parser.add_argument("--wall-to-cpu", action="store_true", help="scale wall seconds per attempt by the jobs' CPU/wall (older runs)")
    parser.add_argument("--families", action="store_true", help="one table per family of the held-out objects instead of per split")
    args = parser.parse_args(argv)
    table = pd.concat([run_split_rows(run, args.methods, run.name, args.wall_to_cpu, args.families) for run in args.runs], ignore_index=True)
    table["method"] = pd.Categorical(table["method"], args.methods, ordered=True)
    table = table.sort_values(["subset", "method"], kind="stable")
    print(markdown(table))
    if args.families:
        return 0
    splits = ("household split", "shapes split", "benchmark split")
    print("| run | " + " | ".join(f"evaluator AUC, held ({name})" for name in splits) + " |")
    print("| --- |" + " ---: |" * len(splits))
    for run in args.runs:
        auc = evaluator_auc(run, split_subsets(pd.read_parquet(run / "results" / "objects" / "catalog.parquet")))
        print(f"| {run.name} | " + " | ".join(f"{auc.get(name, float('nan')):.3f}" for name in splits) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
