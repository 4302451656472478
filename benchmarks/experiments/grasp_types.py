"""Optimization from scratch per grasp type on household objects at real size on a table: what each type holds.

    python benchmarks/experiments/grasp_types.py OUT_DIR [--families bowl hammer spatula can] [--objects-per-family 1]
        [--objects household-bowl-037 ...] [--types power pinch tripod lateral] [--n 16] [--seeds 0 [1 ...]] [--threads 1]
        [--report-only]

The objects are the first ``--objects-per-family`` of each family in the household split (``objects/household_split.yaml``),
or the household objects named by ``--objects`` (e.g. training instances, which a dataset batch uses), generated in
metres standing on z = 0 with z up. For each seed and type, one run of ``dexlite grasp`` (``api.grasp``) on all of
them: ``--from-scratch`` with ``optimize_grasps.grasp_types`` set to that type only, ``--n`` starts per object at its
real size, standing with +z up, lift-tested and pushed from six directions (the tool's tests); its files go to
``OUT_DIR/<type>/`` (one seed) or ``OUT_DIR/seed<k>/<type>/``. Prints, and writes to ``OUT_DIR/grasp_types.md``, per
family and type and for all objects, the seeds pooled: the share of attempts within the energy thresholds
(``optimize_grasps.thresholds``, what curation keeps), held per attempt in the lift test and held in the lift test and
against all six pushes (Wilson 95% intervals), held and within the thresholds, distinct held grasps per object and
seed (the tool's distinct labels, lift test) and those within the thresholds (near what a dataset batch keeps), the
start depth of the held grasps (median and p90, mm) and the most common failure reasons; and each run's CPU-seconds
(this process, all its threads, and its child processes). Per-object rows (one per seed) go to
``OUT_DIR/grasp_types.csv``. ``--report-only`` tabulates runs already in ``OUT_DIR`` (same arguments) into
``grasp_types_report.md`` and ``grasp_types_report.csv`` instead, without their CPU-seconds.
"""

from __future__ import annotations

import argparse
import csv
import resource
import sys
from collections import Counter
from pathlib import Path

import numpy as np

DEFAULT_FAMILIES = ("bowl", "hammer", "spatula", "can")


def cpu_seconds() -> float:
    """User and system CPU-seconds of this process (all threads) and its finished child processes."""
    return sum(u.ru_utime + u.ru_stime for u in (resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)))


def split_objects(families: list[str], per_family: int) -> dict[str, object]:
    """Object id -> mesh (metres) of the first ``per_family`` household-split objects of each family, in split order."""
    from dexlite_pipeline.objects.household import household_object, parse_household_id
    from dexlite_pipeline.objects.sources import household_benchmark_list

    chosen: dict[str, object] = {}
    for family in families:
        ids = [i for i in household_benchmark_list() if parse_household_id(i)[0] == family][:per_family]
        if not ids:
            raise SystemExit(f"grasp_types.py: error: no household-split object of family {family!r}")
        chosen.update({i: household_object(i).mesh for i in ids})
    return chosen


def named_objects(ids: list[str]) -> dict[str, object]:
    """Object id -> mesh (metres) of the named household objects."""
    from dexlite_pipeline.objects.household import household_object

    return {i: household_object(i).mesh for i in ids}


def only(grasp_type: str) -> dict:
    """The config overlay that makes every start of ``grasp_type``."""
    from dexlite_pipeline.optim.grasp_types import TYPE_NAMES

    return {"optimize_grasps": {"grasp_types": {name: 1.0 if name == grasp_type else 0.0 for name in TYPE_NAMES}}}


def per_object_rows(out: Path, grasp_type: str, seed: int = 0) -> list[dict]:
    """One row per object of a finished run: attempts, within the energy thresholds, held (lift), held in both tests,
    distinct held, start depths, failure reasons; the recorded ``grasp_type`` of every attempt is checked."""
    from dexlite_pipeline.io.grasp_store import grasp_types, read_grasp_store
    from dexlite_pipeline.objects.household import parse_household_id
    from dexlite_pipeline.optim.config import OptimizeGraspsConfig

    grasps = read_grasp_store(out / "all_grasps.zarr")
    recorded = set(grasp_types(grasps).tolist())
    if recorded != {grasp_type}:
        raise SystemExit(f"grasp_types.py: error: the {grasp_type} run recorded grasp types {sorted(recorded)}")
    held = np.asarray(grasps.arrays["lift_success"], bool)
    both = held & np.asarray(grasps.arrays["six_dir_success"], bool)
    labels = np.asarray(grasps.arrays["distinct_label"])
    depth = np.asarray(grasps.arrays["initial_penetration_mm"], np.float64)
    reasons = np.asarray(grasps.arrays["failure_reason"], dtype=object)
    passing = np.asarray(OptimizeGraspsConfig().thresholds.passes(grasps.arrays), bool)  # what curation's energy filter keeps
    rows = []
    for object_id in sorted(set(grasps.object_id.tolist())):
        mine = grasps.object_id == object_id
        rows.append({"type": grasp_type, "seed": seed, "object_id": object_id.removeprefix("user-"),
                     "family": parse_household_id(object_id.removeprefix("user-"))[0], "attempts": int(mine.sum()),
                     "passing": int(passing[mine].sum()), "held": int(held[mine].sum()), "passing_held": int((passing & held)[mine].sum()),
                     "distinct_passing": len(set(labels[mine & held & passing].tolist())), "held_six": int(both[mine].sum()),
                     "distinct": len(set(labels[mine & held].tolist())), "depths_mm": depth[mine & held].tolist(),
                     "failures": Counter(str(r).split(":")[0] for r in reasons[mine & ~held])})  # fmt: skip
    return rows


def rate_cell(count: int, attempts: int) -> str:
    from dexlite_pipeline.evaluation.rates import wilson_interval

    if not attempts:
        return "-"
    low, high = wilson_interval(np.arange(attempts) < count)
    return f"{count}/{attempts} = {100 * count / attempts:.0f}% ({100 * low:.0f}–{100 * high:.0f}%)"


def table(rows: list[dict], families: list[str], types: list[str]) -> list[str]:
    lines = ["| family | type | objects | within energy thresholds | held / attempts (lift) | held / attempts (lift and six pushes) "
             "| within thresholds and held (lift) | distinct held / object | distinct held within thresholds / object "
             "| start depth of held, median / p90 mm | most common failures |",
             "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]  # fmt: skip
    for family in [*families, "**all objects**"]:
        for grasp_type in types:
            group = [r for r in rows if r["type"] == grasp_type and (family.startswith("**") or r["family"] == family)]
            if not group:
                continue
            attempts = sum(r["attempts"] for r in group)
            depths = [d for r in group for d in r["depths_mm"]]
            depth = f"{np.median(depths):.2f} / {np.percentile(depths, 90):.2f}" if depths else "-"
            failures = sum((r["failures"] for r in group), Counter())
            common = ", ".join(f"{reason} {count}" for reason, count in failures.most_common(3)) or "-"
            lines.append(f"| {family} | {grasp_type} | {len({r['object_id'] for r in group})} | "
                         f"{rate_cell(sum(r['passing'] for r in group), attempts)} | {rate_cell(sum(r['held'] for r in group), attempts)} | "
                         f"{rate_cell(sum(r['held_six'] for r in group), attempts)} | {rate_cell(sum(r['passing_held'] for r in group), attempts)} | "
                         f"{np.mean([r['distinct'] for r in group]):.1f} | {np.mean([r['distinct_passing'] for r in group]):.1f} | "
                         f"{depth} | {common} |")  # fmt: skip
    return lines


def main(argv: list[str] | None = None) -> int:
    from dexlite_pipeline.optim.grasp_types import TYPE_NAMES

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("--families", nargs="+", default=list(DEFAULT_FAMILIES))
    parser.add_argument("--objects-per-family", type=int, default=1)
    parser.add_argument("--types", nargs="+", choices=TYPE_NAMES, default=list(TYPE_NAMES))
    parser.add_argument("--n", type=int, default=16, help="starts per object and type")
    parser.add_argument("--objects", nargs="+", help="household object ids instead of the split's first of each family")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0])
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--report-only", action="store_true", help="tabulate the runs already in OUT_DIR without running them again")
    args = parser.parse_args(argv)
    from dexlite_pipeline.api import grasp

    if args.objects:
        from dexlite_pipeline.objects.household import parse_household_id

        meshes = dict.fromkeys(args.objects) if args.report_only else named_objects(args.objects)
        args.families = list(dict.fromkeys(parse_household_id(i)[0] for i in args.objects))
    else:
        meshes = split_objects(args.families, args.objects_per_family)
    report = ["# Optimization from scratch per grasp type", "", f"Command: `{' '.join(['python', *sys.argv])}`", "",
              f"Objects: {', '.join(meshes)}; {args.n} starts per object and type at real size, standing on a table (+z up), "
              f"seed(s) {', '.join(map(str, args.seeds))}, {args.threads} thread(s).", ""]  # fmt: skip
    rows, costs = [], []
    for seed in args.seeds:
        for grasp_type in args.types:
            out = args.out_dir / grasp_type if len(args.seeds) == 1 else args.out_dir / f"seed{seed}" / grasp_type
            cpu = cpu_seconds()
            if not args.report_only:
                grasp(meshes, n=args.n, seed=seed, out_dir=out, from_scratch=True, upright_axis="+z", threads=args.threads,
                      config=only(grasp_type), overwrite=True)  # fmt: skip
            costs.append(f"{grasp_type} seed {seed} " + ("(not rerun)" if args.report_only else f"{cpu_seconds() - cpu:.0f} CPU-s"))
            rows += per_object_rows(out, grasp_type, seed)
            print(f"{grasp_type} seed {seed}: done ({costs[-1]})", flush=True)
    report += [f"Runs: {', '.join(costs)}.", "", *table(rows, args.families, args.types), ""]
    print("\n".join(report))
    name = "grasp_types_report" if args.report_only else "grasp_types"
    (args.out_dir / f"{name}.md").write_text("\n".join(report))
    with open(args.out_dir / f"{name}.csv", "w", newline="") as file:
        fields = ["type", "seed", "object_id", "family", "attempts", "passing", "held", "held_six", "passing_held", "distinct", "distinct_passing",
                  "start_depth_median_mm"]
        writer = csv.DictWriter(file, fieldnames=fields)
        writer.writeheader()
        for r in rows:
            writer.writerow({**{k: r[k] for k in fields[:-1]},
                             "start_depth_median_mm": f"{np.median(r['depths_mm']):.3f}" if r["depths_mm"] else ""})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
