"""Distinct held grasps per CPU-hour of a dataset's batches, per family, and model-made batches against optimization-only
batches on the same families.

    python benchmarks/experiments/batch_yield.py DATASET --model 0030 0031 ... --optimization 0017 0026 [--families bowl ...]

Every batch of a dataset was tested alike (the lift and six-direction tests on the table, the 2 mm start cap), so a
batch's yield is the distinct held grasps it added (``distinct_held_added``: a grasp like one an earlier batch held on
the same object counts nothing) over the CPU-seconds it recorded (every stage, preparation included). A batch's CPU
is not split by object in its record; within a batch each object is charged an equal share (the starts per object are
equal). Per family: objects, distinct held grasps added, and distinct per CPU-hour of each kind. Then the comparison
on equal terms: what optimization-only batches would have made on the model batches' own objects (each family's
distinct held per object and CPU per object of the optimization batches, weighted by the model batches' objects per
family), against what the model batches made.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np
import pandas as pd


def family(object_id: str) -> str:
    """``household-bowl-012`` -> ``bowl``; other sources by their prefix."""
    parts = object_id.split("-")
    return parts[1] if parts[0] == "household" and len(parts) >= 3 else parts[0]


def batch_family_rows(dataset: Path, batch: str, batches: pd.DataFrame) -> list[dict]:
    """One row per family of ``batch``: objects, distinct held grasps added, CPU-seconds charged (equal share per object)."""
    arrays = np.load(dataset / "grasps" / f"batch_{batch}.npz", allow_pickle=False)
    ids, labels = arrays["object_id"].astype(str), arrays["distinct_label"]
    earlier = earlier_labels(dataset, batch, batches, set(ids))
    cpu = sum(json.loads(batches.loc[batch, "cpu_seconds"]).values())
    objects = sorted(set(ids))
    rows: dict[str, dict] = defaultdict(lambda: {"objects": 0, "distinct_added": 0})
    for object_id in objects:
        mine = set(labels[(ids == object_id) & (labels >= 0)].tolist())
        row = rows[family(object_id)]
        row["objects"] += 1
        row["distinct_added"] += len(mine - earlier.get(object_id, set()))
    return [{"batch": batch, "kind": batches.loc[batch, "kind"], "family": name, **row, "cpu_s": cpu * row["objects"] / len(objects)}
            for name, row in sorted(rows.items())]  # fmt: skip


def earlier_labels(dataset: Path, batch: str, batches: pd.DataFrame, object_ids: set[str]) -> dict[str, set[int]]:
    """The distinct labels the batches before ``batch`` hold on ``object_ids`` (labels are consistent over the dataset)."""
    held: dict[str, set[int]] = defaultdict(set)
    for previous in batches.index:
        if previous >= batch:
            break
        arrays = np.load(dataset / "grasps" / f"batch_{previous}.npz", allow_pickle=False)
        ids, labels = arrays["object_id"].astype(str), arrays["distinct_label"]
        for object_id in object_ids & set(ids.tolist()):
            held[object_id] |= set(labels[(ids == object_id) & (labels >= 0)].tolist())
    return held


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", type=Path)
    parser.add_argument("--model", nargs="+", required=True, help="model-made batch ids")
    parser.add_argument("--optimization", nargs="+", required=True, help="optimization-only batch ids")
    parser.add_argument("--families", nargs="*", default=None, help="only these families (default: those of the model batches)")
    args = parser.parse_args()

    batches = pd.read_csv(args.dataset / "batches.csv", dtype={"batch": str}).set_index("batch").sort_index()
    rows = pd.DataFrame([row for batch in [*args.model, *args.optimization] for row in batch_family_rows(args.dataset, batch, batches)])
    families = args.families or sorted(set(rows[rows.kind == "model"].family))
    rows = rows[rows.family.isin(families)]
    per_family = rows.groupby(["family", "kind"])[["objects", "distinct_added", "cpu_s"]].sum()
    per_family["distinct_per_object"] = per_family.distinct_added / per_family.objects
    per_family["distinct_per_cpu_hour"] = per_family.distinct_added / (per_family.cpu_s / 3600)
    print(per_family.round(2).to_string())
    model = per_family.xs("model", level="kind")
    optimization = per_family.xs("optimization", level="kind").reindex(model.index)
    if optimization.objects.isna().any():
        missing = ", ".join(optimization.index[optimization.objects.isna()])
        raise SystemExit(f"no optimization batch holds family {missing}: no comparison on equal terms")
    made = model.distinct_added.sum() / (model.cpu_s.sum() / 3600)
    expected_distinct = (model.objects * optimization.distinct_per_object).sum()
    expected_cpu = (model.objects * optimization.cpu_s / optimization.objects).sum()
    would = expected_distinct / (expected_cpu / 3600)
    print(f"\nmodel batches {', '.join(args.model)}: {model.distinct_added.sum():.0f} distinct held added in {model.cpu_s.sum():.0f} CPU-s "
          f"= {made:.0f} per CPU-hour")
    print(f"optimization batches {', '.join(args.optimization)} on the same objects per family: {expected_distinct:.0f} distinct held "
          f"in {expected_cpu:.0f} CPU-s = {would:.0f} per CPU-hour")
    print(f"ratio: {made / would:.2f}x")


if __name__ == "__main__":
    main()
