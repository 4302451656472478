"""`dexlite grasp` on a held-out split as generated and turned about the vertical: how much the results depend on yaw.

    python benchmarks/experiments/yaw_sensitivity.py OUT_DIR [--split household|shapes|benchmark] [--forms generated turned] [--seeds 0 1 2]
        [--yaws-per-object 1] [--n 16] [--limit K] [--objects ID ...] [--threads 1] [-- EXTRA dexlite grasp ARGS]

The objects are the household split's (``objects/household_split.yaml``: three of each family, never trained on;
``--split shapes``: the shapes split's, ``objects/shapes_split.yaml``: the shape families and perturbed instances of
every family; ``--limit K``: the first K), generated in metres standing on z = 0 with z up. ``--split benchmark``: the
benchmark split's procedural pybullet_data objects (``objects/benchmark_split.yaml``), placed as their URDF places them;
they have no real size, so each is grasped at the training radii (``--resize-to-training``, as the pipeline samples and
optimizes them) and rests in its stable pose (no ``--upright-axis``); their table group is "procedural". ``--objects``:
these ids instead of a split, all procedural (placed as the benchmark split's) or all household (as the household
split's), e.g. objects of no split and no dataset batch on which to choose a setting. Per seed, each
is written as OBJ into ``OUT_DIR/seed_<s>/generated/`` as generated and into ``OUT_DIR/seed_<s>/turned/`` turned about
the vertical through its bounding-box centre by a yaw drawn uniformly from [0, 2π) by ``default_rng([seed, crc32(object id)])``
(``--yaws-per-object K``: K turned copies ``<id>_yaw<k>.obj``); the yaws go to ``OUT_DIR/seed_<s>/yaws.csv``. Then one
``dexlite grasp`` call per folder with the shipped model: ``--n`` samples per object ranked by its evaluator,
post-optimized and lift-tested on a table, no optimization top-up (``--min-distinct 0``), and (household and shapes
splits) ``--upright-axis +z`` so that a turned copy rests in the same pose as the generated mesh and only its heading
differs. Arguments after ``--`` go to both calls (``-- --from-scratch``: optimization from scratch on the same files; an inline
``--config-json`` there is given with the seed). ``--forms turned``: the
turned copies only (the held-out measure at seeded yaw).

Writes attempts, held, held and six-direction passed, distinct held grasps and the held grasps' median start depth per
object, form and seed to ``OUT_DIR/yaw_objects.csv``; prints, and writes to ``OUT_DIR/yaw_sensitivity.md``, per family
and for all objects, per seed and seeds pooled: held per attempt (with a Wilson 95% interval on the pooled rows), held
and passed the six-direction test per attempt, mean distinct held grasps per object (per turned copy) and the median
start depth of the held grasps (mm inside the object), as generated and turned, and each call's CPU-seconds. A turned
mesh also gives the model other inputs, so its samples differ even at the same seed: read a difference against the
Wilson intervals and the spread between seeds.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import zlib
from pathlib import Path

import numpy as np

FORMS = ("generated", "turned")


def yaws_of(object_id: str, seed: int, count: int) -> np.ndarray:
    """The object's ``count`` seeded yaws (radians, uniform in [0, 2π))."""
    return np.random.default_rng([seed, zlib.crc32(object_id.encode())]).uniform(0.0, 2 * np.pi, count)


def turned_about_vertical(mesh, yaw: float):
    """A copy of ``mesh`` turned by ``yaw`` about the z axis through its bounding-box centre."""
    import trimesh

    turned = mesh.copy()
    turned.apply_transform(trimesh.transformations.rotation_matrix(yaw, [0.0, 0.0, 1.0], point=mesh.bounds.mean(axis=0)))
    return turned


def write_meshes(seed_dir: Path, meshes: dict, seed: int, yaws_per_object: int) -> dict[str, dict[str, tuple[str, float]]]:
    """Writes ``generated/`` and ``turned/`` and ``yaws.csv``; returns form -> file stem -> (object id, yaw)."""
    copies: dict[str, dict[str, tuple[str, float]]] = {form: {} for form in FORMS}
    for form in FORMS:
        (seed_dir / form).mkdir(parents=True, exist_ok=True)
    for object_id, mesh in meshes.items():
        mesh.export(seed_dir / "generated" / f"{object_id}.obj")
        copies["generated"][object_id] = (object_id, 0.0)
        for k, yaw in enumerate(yaws_of(object_id, seed, yaws_per_object)):
            turned_about_vertical(mesh, yaw).export(seed_dir / "turned" / f"{object_id}_yaw{k}.obj")
            copies["turned"][f"{object_id}_yaw{k}"] = (object_id, float(yaw))
    with open(seed_dir / "yaws.csv", "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["object_id", "file", "yaw_rad", "yaw_deg"])
        for stem, (object_id, yaw) in copies["turned"].items():
            writer.writerow([object_id, f"turned/{stem}.obj", f"{yaw:.6f}", f"{np.degrees(yaw):.2f}"])
    return copies


def held_cell(held: int, attempts: int, with_interval: bool) -> str:
    from dexlite_pipeline.evaluation.rates import wilson_interval

    if not attempts:
        return "-"
    text = f"{held}/{attempts} = {100 * held / attempts:.1f}%"
    if with_interval:
        low, high = wilson_interval(np.arange(attempts) < held)
        text += f" ({100 * low:.1f}–{100 * high:.1f}%)"
    return text


def family_of(object_id: str) -> str:
    """The table's group of a split object: its family, with " (perturbed)" for a perturbed instance; "procedural" for a
    procedural pybullet_data object (the benchmark split)."""
    from dexlite_pipeline.objects.household import parse_household_id

    if object_id.startswith("pb-random-"):
        return "procedural"
    parsed = parse_household_id(object_id)
    return parsed.family + (" (perturbed)" if parsed.variant else "")


def family_table(rows: list[dict], with_interval: bool, forms: tuple[str, ...] = FORMS) -> list[str]:
    """Per family (in the split's order) and for all objects, per form: held per attempt, held and passed the six-direction
    test per attempt, mean distinct held per object and the median start depth of the held grasps (mm inside)."""
    head = " | ".join(f"{form}: held / attempts | {form}: six directions | {form}: distinct / object | {form}: start depth of held, "
                      "median mm" for form in forms)  # fmt: skip
    lines = [f"| family | objects | {head} |", "| --- | ---: |" + " ---: | ---: | ---: | ---: |" * len(forms)]
    families = list(dict.fromkeys(r["family"] for r in rows))
    groups = [(family, [r for r in rows if r["family"] == family]) for family in families] + [("**all objects**", rows)]
    for name, group in groups:
        if not group:
            continue
        cells = []
        for form in forms:
            mine = [r for r in group if r["form"] == form]
            attempts = sum(r["attempts"] for r in mine)
            depths = [d for r in mine for d in r["held_start_mm"]]
            cells += [held_cell(sum(r["held"] for r in mine), attempts, with_interval),
                      f"{100 * sum(r['six'] for r in mine) / attempts:.1f}%" if attempts else "-",
                      f"{np.mean([r['distinct'] for r in mine]):.2f}" if mine else "-",
                      f"{np.median(depths):.2f}" if depths else "-"]  # fmt: skip
        lines.append(f"| {name} | {len({r['object_id'] for r in group})} | " + " | ".join(cells) + " |")
    return lines


def split_meshes(split: str, limit: int | None, object_ids: list[str] | None = None) -> dict:
    """Object id -> trimesh of the split's first ``limit`` objects (all with None), or of ``object_ids`` instead of a split:
    household and shapes objects generated in metres standing on z = 0; procedural objects (the benchmark split's,
    ``pb-random-NNN``) as their URDF places them (scale and rotation), in its units."""
    from dexlite_pipeline.objects.asset_building import load_source_mesh
    from dexlite_pipeline.objects.household import household_object
    from dexlite_pipeline.objects.sources import benchmark_object_list, household_benchmark_list, pybullet_random_source_of, shapes_benchmark_list

    if object_ids is None:
        object_ids = {"benchmark": benchmark_object_list, "household": household_benchmark_list, "shapes": shapes_benchmark_list}[split]()[:limit]
    return {object_id: load_source_mesh(pybullet_random_source_of(object_id)) if is_procedural(object_id) else household_object(object_id).mesh
            for object_id in object_ids}


def is_procedural(object_id: str) -> bool:
    """Whether ``object_id`` names a procedural pybullet_data object (placed like the benchmark split's) rather than a
    generated household one."""
    return object_id.startswith("pb-random-")


def objects_kind(object_ids: list[str]) -> str:
    """'benchmark' when every id of ``--objects`` is procedural, 'household' when none is (their placement: resized to
    the training radii, or standing at real size); ValueError for a mix, which no one placement fits."""
    procedural = {is_procedural(object_id) for object_id in object_ids}
    if len(procedural) != 1:
        raise ValueError("--objects: give procedural (pb-random-NNN) or household ids, not both")
    return "benchmark" if procedural.pop() else "household"


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    config = {}  # an extra --config-json: merged under the seed each call sets (one --config-json reaches dexlite grasp)
    if "--config-json" in extra:
        at = extra.index("--config-json")
        config = json.loads(extra[at + 1])
        extra = extra[:at] + extra[at + 2:]
    own = argv[: argv.index("--")] if "--" in argv else argv
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("--split", choices=("household", "shapes", "benchmark"), default="household",
                        help="the held-out split (default: household)")
    parser.add_argument("--forms", nargs="+", choices=FORMS, default=list(FORMS), help="which copies to grasp (default: both)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--yaws-per-object", type=int, default=1)
    parser.add_argument("--n", type=int, default=16)
    parser.add_argument("--limit", type=int, default=None, help="the first K objects of the split (default: all)")
    parser.add_argument("--objects", nargs="+", default=None, metavar="ID",
                        help="object ids instead of a split, all procedural (pb-random-NNN, placed as the benchmark split's) or "
                        "all household (standing at real size): e.g. objects of no split and no dataset batch, to choose a "
                        "setting on objects other than those it is then measured on")
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args(own)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from grasp_check_meshes import per_mesh_counts, run_grasp

    forms = tuple(form for form in FORMS if form in args.forms)
    try:
        kind = args.split if args.objects is None else objects_kind(args.objects)
    except ValueError as error:
        parser.error(str(error))
    meshes = split_meshes(args.split, args.limit, args.objects)
    top_up = [] if "--from-scratch" in extra else ["--min-distinct", "0"]  # the model's own grasps: no optimization top-up
    placement = ["--resize-to-training"] if kind == "benchmark" else ["--upright-axis", "+z"]
    grasp_args = ["--n", str(args.n), *top_up, *placement, *extra]
    what = f"the {args.split} split" if args.objects is None else f"{len(args.objects)} {kind} objects given by id"
    report = [f"# `dexlite grasp` on {what}, {' and '.join(forms)} about the vertical", "",
              f"Command: `{' '.join(['python', *sys.argv])}`", "",
              f"{len(meshes)} objects, {args.n} grasps each, {args.yaws_per_object} turned cop"
              f"{'y' if args.yaws_per_object == 1 else 'ies'} per object and seed; `dexlite grasp` arguments: "
              f"`{' '.join(grasp_args)}`.", ""]  # fmt: skip
    rows = []
    for seed in args.seeds:
        seed_dir = args.out_dir / f"seed_{seed}"
        copies = write_meshes(seed_dir, meshes, seed, args.yaws_per_object)
        seed_rows, costs = [], []
        for form in forms:
            out = seed_dir / f"grasp_{form}"
            cpu, wall = run_grasp(str(seed_dir / form), out, seed, args.threads, grasp_args, None, config)
            costs.append(f"{form} {cpu:.0f} CPU-s ({wall:.0f} s wall)")
            counts = per_mesh_counts(out)
            for stem, (object_id, yaw) in copies[form].items():
                count = counts.get(f"user-{stem}", {"attempts": 0, "held": 0, "distinct": 0, "six": 0, "held_start_mm": []})
                seed_rows.append({"seed": seed, "object_id": object_id, "family": family_of(object_id), "form": form,
                                  "yaw_deg": round(float(np.degrees(yaw)), 2), "attempts": count["attempts"], "held": count["held"],
                                  "distinct": count["distinct"], "six": count["six"], "held_start_mm": count["held_start_mm"]})  # fmt: skip
        rows += seed_rows
        missing = sorted({f"{r['object_id']} ({r['form']})" for r in seed_rows if not r["attempts"]})
        section = [f"## Seed {seed}", "", f"`dexlite grasp` calls: {', '.join(costs)}.", "",
                   *([f"No grasps recorded (counted as 0 of 0): {', '.join(missing)}.", ""] if missing else []),
                   *family_table(seed_rows, False, forms), ""]  # fmt: skip
        print("\n".join(section), flush=True)
        report += section
    pooled = [f"## Seeds {', '.join(map(str, args.seeds))} pooled (Wilson 95% intervals)", "", *family_table(rows, True, forms), ""]
    print("\n".join(pooled))
    (args.out_dir / "yaw_sensitivity.md").write_text("\n".join(report + pooled))
    with open(args.out_dir / "yaw_objects.csv", "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=[k for k in rows[0] if k != "held_start_mm"] + ["held_start_median_mm"])
        writer.writeheader()
        for row in rows:
            depths = row["held_start_mm"]
            writer.writerow({**{k: v for k, v in row.items() if k != "held_start_mm"},
                             "held_start_median_mm": f"{np.median(depths):.3f}" if depths else ""})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
