"""The evaluation's held-out rows restricted to named sets of objects (the household split, the benchmark split).

``metrics.csv`` pools every held-out object of a run; a run that holds out two splits (the household model's
profile: the 36-object household split and the 48-object benchmark split) is read per split from
``per_object.csv`` here: attempts, held per attempt with its Wilson 95% interval, six-direction success, distinct
held grasps per object, and CPU-seconds per distinct held grasp (the method's seconds per attempt from
``metrics.csv`` times the set's attempts, over the set's distinct held grasps).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from dexlite_pipeline.evaluation.rates import wilson_interval

SUBSET_COLUMNS = ("method", "subset", "objects", "attempts", "held", "held_rate", "held_ci95_low", "held_ci95_high", "six_dir_rate",
                  "distinct_held_per_object", "objects_with_min_distinct", "cpu_seconds_per_distinct_held")  # fmt: skip
MIN_DISTINCT_HELD = 4  # objects_with_min_distinct: the share of a set's objects with at least this many distinct held grasps


def subset_rows(
    metrics: pd.DataFrame, per_object: pd.DataFrame, subsets: Mapping[str, Iterable[str]], methods: Iterable[str], split: str = "heldout",
) -> pd.DataFrame:
    """One row per (method, subset) with evaluated objects: the columns ``SUBSET_COLUMNS``.

    ``subsets``: name -> object ids; ``methods``: the methods wanted (those the run did not evaluate are left out).
    Held and six-direction counts are rebuilt from each object's rates and attempts (``n_grasps``);
    ``objects_with_min_distinct`` is the share of the set's objects with at least ``MIN_DISTINCT_HELD`` distinct held grasps."""
    rows = []
    table = per_object[per_object["split"] == split]
    for method in methods:
        mine = table[table["method"] == method]
        seconds = metrics.loc[(metrics["method"] == method) & (metrics["split"] == split), "seconds_per_grasp"]
        seconds_per_attempt = float(seconds.iloc[0]) if len(seconds) else math.nan
        for name, object_ids in subsets.items():
            part = mine[mine["object_id"].isin(set(object_ids))]
            if part.empty:
                continue
            attempts = int(part["n_grasps"].sum())
            held = int(np.rint(part["lift_success_rate"] * part["n_grasps"]).sum())
            six_dir = float(np.rint(part["six_dir_success_rate"].fillna(0) * part["n_grasps"]).sum())
            distinct = int(part["n_distinct_held"].sum())
            low, high = wilson_interval(np.arange(attempts) < held)
            rows.append({
                "method": method, "subset": name, "objects": len(part), "attempts": attempts, "held": held,
                "held_rate": held / attempts if attempts else math.nan, "held_ci95_low": low, "held_ci95_high": high,
                "six_dir_rate": six_dir / attempts if attempts else math.nan, "distinct_held_per_object": distinct / len(part),
                "objects_with_min_distinct": float((part["n_distinct_held"] >= MIN_DISTINCT_HELD).mean()),
                "cpu_seconds_per_distinct_held": seconds_per_attempt * attempts / distinct if distinct else math.nan,
            })  # fmt: skip
    return pd.DataFrame(rows, columns=list(SUBSET_COLUMNS))


def split_subsets(catalog: pd.DataFrame) -> dict[str, list[str]]:
    """The named held-out object sets of a run's catalog: the household split's, the shapes split's and the benchmark
    split's prepared objects (a set with none is left out)."""
    from dexlite_pipeline.objects.sources import benchmark_object_ids, household_benchmark_list, shapes_benchmark_list

    prepared = set(catalog.loc[catalog["status"] == "ok", "object_id"])
    named = {"household split": household_benchmark_list(), "shapes split": shapes_benchmark_list(),
             "benchmark split": sorted(benchmark_object_ids())}
    return {name: [o for o in ids if o in prepared] for name, ids in named.items() if prepared & set(ids)}


def family_subsets(object_ids: Iterable[str]) -> dict[str, list[str]]:
    """The objects by family (``objects.family.object_family``), families in name order."""
    from dexlite_pipeline.objects.family import object_family

    families: dict[str, list[str]] = {}
    for object_id in sorted(set(object_ids)):
        families.setdefault(object_family(object_id), []).append(object_id)
    return dict(sorted(families.items()))


# Stage names of metrics.csv's seconds_per_grasp_by_stage -> the rule whose jobs ran them.
STAGE_RULES = {"optimized": "optimize_grasps", "sample": "sample_grasps", "ranking": "sample_grasps", "post": "post_optimize",
               "random_post": "post_optimize"}


def cpu_over_wall(run: Path, rule: str) -> float:
    """CPU time over wall time of a rule's jobs (Snakemake's benchmark files of the run); NaN when the run has none."""
    jobs = [pd.read_csv(path, sep="\t").iloc[0] for path in sorted((run / "logs" / "benchmarks").glob(f"{rule}*.tsv"))]
    wall = sum(float(j["s"]) for j in jobs)
    return sum(float(j["cpu_time"]) for j in jobs) / wall if wall > 0 else math.nan


def with_cpu_seconds(run: Path, metrics: pd.DataFrame) -> pd.DataFrame:
    """``metrics`` of a run made before the stages counted process CPU seconds (their seconds were wall time), with
    each method's seconds per attempt rebuilt from its stages' wall seconds times their jobs' CPU time over wall time
    (Snakemake's benchmark files): on shared cores wall time overstates a stage's cost by what it waited."""
    factor = {rule: cpu_over_wall(run, rule) for rule in set(STAGE_RULES.values())}
    metrics = metrics.copy()
    for index, text in metrics["seconds_per_grasp_by_stage"].items():
        if isinstance(text, str) and text:
            stages = dict(part.split("=") for part in text.split(";"))
            metrics.loc[index, "seconds_per_grasp"] = sum(float(v) * factor[STAGE_RULES[k]] for k, v in stages.items())
    return metrics


def run_split_rows(run: Path, methods: Iterable[str], label: str, wall_to_cpu: bool = False, by_family: bool = False) -> pd.DataFrame:
    """``subset_rows`` of a finished run folder (its metrics, per-object table and catalog) per ``split_subsets`` (with
    ``by_family``: per ``family_subsets`` of its held-out objects), with a first column ``run`` = ``label``;
    ``wall_to_cpu``: the costs of a run made before the stages counted CPU seconds, rescaled (``with_cpu_seconds``)."""
    results = run / "results"
    metrics = pd.read_csv(results / "eval" / "metrics.csv")
    metrics = with_cpu_seconds(run, metrics) if wall_to_cpu else metrics
    per_object = pd.read_csv(results / "eval" / "per_object.csv")
    if by_family:
        subsets = family_subsets(per_object.loc[per_object["split"] == "heldout", "object_id"].astype(str))
    else:
        subsets = split_subsets(pd.read_parquet(results / "objects" / "catalog.parquet"))
    rows = subset_rows(metrics, per_object, subsets, methods)
    rows.insert(0, "run", label)
    return rows
