"""Optimization from scratch with one hand on the household split: held per attempt and why the others failed.

    python benchmarks/experiments/hand_split.py OUT_DIR --hand leap --seeds 0 1 2 [--n 16] [--limit K] [--label after] [--config-json JSON]
                                                [--objects ID ...] [--type-rounds R]

What ``dexlite grasp MESHES --from-scratch --hand H --n 16 --upright-axis +z`` does, without its pictures and stores:
the household split's objects (``objects/household_split.yaml``, ``--limit K``: the first K) are generated in metres
standing on z = 0 into ``OUT_DIR/meshes/`` (once), prepared and stood on their tables as the grasp tool prepares
them (``prepare_meshes``, the preparation's seed 0 for every seed, so the seeds share the objects), then per seed
optimized from scratch (``synthesize_from_scratch``), lift- and six-direction-tested (the tool's ``lift_tested``:
2 mm start cap, hopeless optimizations not simulated) and labelled distinct (``distinct_labels``), one thread.
``--config-json``: config sections over the defaults, e.g. ``'{"optimize_grasps": {"grasp_types": {"pinch": 1.0}}}'``.
``--objects``: household object ids instead of the split (``household-<family>-<instance>``), e.g. instances of no split
and no dataset batch, to choose a setting on objects other than those it is then measured on. ``--type-rounds R``: each
object's starts in R rounds, the later ones dealt to the grasp types that held on it (``dexlite grasp --type-rounds``).

Per seed it prints, and appends as a JSON line to ``OUT_DIR/hand_split.jsonl``: held per attempt with a Wilson 95%
interval, held and six directions, distinct held grasps per object, the held grasps' start depth median (mm), how many
passed the energy thresholds, failures by reason (a grasp that was simulated and not lifted is ``dropped``), and the
process CPU seconds of optimization and tests; then the seeds pooled. The journal's split tables are made of these rows.
Each seed's tested grasps go to ``OUT_DIR/<hand>_<label or run>_seed<S>/tested.npz`` (numeric arrays, object ids, failure
reasons, grasp types and distinct labels).
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter
from pathlib import Path

import numpy as np


def wilson_text(count: int, total: int) -> str:
    from dexlite_pipeline.evaluation.rates import wilson_interval

    low, high = wilson_interval(np.arange(total) < count)
    return f"{count}/{total} = {100 * count / total:.1f}% [{100 * low:.1f}%, {100 * high:.1f}%]"


def failures(tested) -> Counter:
    """Failure reason -> count over the grasps that did not lift ('dropped' for a simulated grasp that fell)."""
    held = np.asarray(tested.arrays["lift_success"], bool)
    reasons = np.asarray(tested.arrays["failure_reason"], dtype=object)[~held]
    return Counter("hopeless" if "hopeless" in str(r) else (str(r).split(":")[0] or "dropped") for r in reasons)


def row_of(tested, labels: np.ndarray, objects: int, cpu_s: float, **keys) -> dict:
    held = np.asarray(tested.arrays["lift_success"], bool)
    six = np.asarray(tested.arrays.get("six_dir_success", np.zeros(len(held), bool)), bool) & held
    depth = np.asarray(tested.arrays["initial_penetration_mm"], np.float64)[held]
    distinct = len({(str(o), int(lab)) for o, lab in zip(tested.object_id[held], labels[held])})
    return {**keys, "attempts": int(len(held)), "held": int(held.sum()), "six": int(six.sum()), "distinct": distinct, "objects": objects,
            "depth_held_mm": depth.tolist(), "passes": int(np.asarray(tested.arrays["passes_energy_thresholds"], bool).sum()),
            "failures": dict(failures(tested).most_common()), "cpu_s": cpu_s}  # fmt: skip


def table_line(row: dict) -> str:
    """One row of the journal's split table: hand, seed, label, held [Wilson 95%], held and six directions, distinct held per
    object, start depth median of the held grasps (mm), energy thresholds passed, failures by reason, CPU-s."""
    reasons = ", ".join(f"{k} {v}" for k, v in row["failures"].items())
    depth = np.median(row["depth_held_mm"]) if row["depth_held_mm"] else float("nan")
    six = wilson_text(row["six"], row["attempts"]).split("/", 1)[0] + " =" + wilson_text(row["six"], row["attempts"]).split(" =", 1)[1]
    return (f"| {row['hand']} | {row['seed']} | {row.get('label', '')} | {wilson_text(row['held'], row['attempts'])} | {six} | "
            f"{row['distinct'] / row['objects']:.2f} | {depth:.2f} | {row['passes']} | {reasons} | {row['cpu_s']:.0f} |")


def pooled(rows: list[dict]) -> dict:
    out = {"hand": rows[0]["hand"], "seed": f"pooled ({len(rows)})", "label": rows[0].get("label", ""), "failures": Counter()}
    for key in ("attempts", "held", "six", "distinct", "objects", "passes", "cpu_s"):
        out[key] = sum(r[key] for r in rows)
    out["depth_held_mm"] = [d for r in rows for d in r["depth_held_mm"]]
    for r in rows:
        out["failures"].update(r["failures"])
    out["failures"] = dict(out["failures"].most_common())
    return out


def tabulate(rows: list[dict]) -> list[str]:
    """Table lines of rows in file order, each hand and label's seeds pooled after its rows (when it has several)."""
    lines = []
    groups: dict[tuple[str, str], list[dict]] = {}
    for row in rows:
        groups.setdefault((row["hand"], row.get("label", "")), []).append(row)
    for group in groups.values():
        group = sorted(group, key=lambda r: r["seed"])
        lines += [table_line(r) for r in group] + ([table_line(pooled(group))] if len(group) > 1 else [])
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("--hand", default="leap")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--n", type=int, default=16)
    parser.add_argument("--limit", type=int, default=None, help="the first K objects of the household split (default: all 36)")
    parser.add_argument("--label", default="", help="a name for this code version in the output rows")
    parser.add_argument("--config-json", type=json.loads, default={}, metavar="JSON", help="config sections over the defaults")
    parser.add_argument("--type-rounds", type=int, default=None, metavar="R", help="optimize in R type rounds (default: one)")
    parser.add_argument("--objects", nargs="+", default=None, metavar="ID", help="household object ids instead of the household split")
    parser.add_argument("--tabulate", action="store_true", help="only print the rows of OUT_DIR/hand_split.jsonl, per hand and label pooled")
    args = parser.parse_args(argv)
    if args.tabulate:
        print("\n".join(tabulate([json.loads(line) for line in (args.out_dir / "hand_split.jsonl").read_text().splitlines() if line])))
        return 0

    from dexlite_pipeline.api import grasp_request
    from dexlite_pipeline.device import set_threads
    from dexlite_pipeline.io.grasp_store import grasp_types
    from dexlite_pipeline.objects.household import household_object
    from dexlite_pipeline.objects.sources import household_benchmark_list
    from dexlite_pipeline.tools.grasp.checks import check_request
    from dexlite_pipeline.tools.grasp.run import GraspRun, RunRecord, prepare_meshes
    from dexlite_pipeline.tools.grasp.selection import distinct_labels

    set_threads(1)  # torch on one thread, as ``dexlite grasp`` by default (the same sums, so the same grasps)
    mesh_dir = args.out_dir / "meshes"
    ids = (args.objects or household_benchmark_list())[: args.limit]
    mesh_dir.mkdir(parents=True, exist_ok=True)
    for object_id in ids:
        if not (mesh_dir / f"{object_id}.obj").is_file():
            household_object(object_id).mesh.export(mesh_dir / f"{object_id}.obj")
    meshes = [str(mesh_dir / f"{object_id}.obj") for object_id in ids]
    rows = []
    for seed in args.seeds:
        out = args.out_dir / f"{args.hand}_{args.label or 'run'}_seed{seed}"
        request = grasp_request(meshes, str(out), n=args.n, from_scratch=True, hand=args.hand, upright_axis="+z", overwrite=True,
                                type_rounds=args.type_rounds,
                                config={**args.config_json, "seed": 0})  # the objects are prepared and stood with seed 0 whatever the run's seed
        checked = check_request(request)
        record = RunRecord()
        prepared = prepare_meshes(request, checked, out / "objects", 5, record)
        run = GraspRun(request, checked, prepared, out, 5, record)
        started = time.process_time()
        tested = run.from_scratch_tested(prepared.assets, seed)
        cpu_s = time.process_time() - started
        labels = distinct_labels(tested, checked.config)
        row = row_of(tested, labels, len(prepared.assets), cpu_s, hand=args.hand, seed=seed, label=args.label)
        rows.append(row)
        with open(args.out_dir / "hand_split.jsonl", "a") as file:
            file.write(json.dumps(row) + "\n")
        np.savez_compressed(out / "tested.npz", **{k: np.asarray(v) for k, v in tested.arrays.items() if np.asarray(v).dtype != object},
                            object_id=np.asarray(tested.object_id, str), failure_reason=np.asarray(tested.arrays["failure_reason"], str),
                            grasp_type=np.asarray(grasp_types(tested), str),
                            distinct_label=np.asarray(labels))  # fmt: skip
        print(table_line(row), flush=True)
    if len(rows) > 1:
        print(table_line(pooled(rows)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
