"""`dexlite grasp` on the household check meshes over several seeds: held and distinct held grasps per mesh.

    python benchmarks/experiments/grasp_check_meshes.py OUT_DIR [--set household|kitchen] [--seeds 0 1 2] [--threads 1] [-- EXTRA dexlite grasp ARGS]

Writes the check meshes (``make_household_meshes.py``: a mug with a handle and a 4 mm wall, a bowl, a 30 cm wine
bottle and a cereal box in metres, and the same mug in millimetres), then per seed runs the default command on the
four metre meshes in one call and on the millimetre mug with ``--units mm``, each into ``OUT_DIR/seed_<s>/``.
Prints, and writes to ``OUT_DIR/check_meshes.md``, per mesh and seed: attempts, held, distinct held grasps (all
sources together) and per source (model, optimization from scratch), and each command's CPU-seconds (its own and its
children's user + system time) and wall seconds. ``--set kitchen``: the kitchen check meshes instead (a bowl with a 4 mm
wall, a plate, a spatula and a hammer lying on the table, metres; ``make_household_meshes.py --set kitchen``), in one
call per seed. ``--config-json`` gives every call config sections (e.g. ``sample.type_mix``). Arguments after ``--`` go to every ``dexlite grasp`` call
(e.g. ``-- --from-scratch``).
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np


def cpu_seconds_of_children() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_grasp(meshes: str, out: Path, seed: int, threads: int, extra: list[str], units: str | None,
              config: dict | None = None) -> tuple[float, float]:
    """One ``dexlite grasp`` call; returns (CPU-seconds, wall seconds). Exit 1 (nothing held) is a result, not an error.
    ``config``: config sections for its ``--config-json``, beside the seed."""
    command = [sys.executable, "-m", "dexlite_pipeline.cli", "grasp", meshes, "--out", str(out), "--overwrite", "--threads", str(threads),
               "--renders", "0", "--config-json", json.dumps({**(config or {}), "seed": seed}), *extra]  # fmt: skip
    if units:
        command += ["--units", units]
    cpu, wall = cpu_seconds_of_children(), time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode not in (0, 1):
        raise SystemExit(f"grasp_check_meshes.py: error: {' '.join(command)} exited {done.returncode}: {done.stderr.strip().splitlines()[-1:]}")
    return cpu_seconds_of_children() - cpu, time.perf_counter() - wall


def per_mesh_counts(out: Path) -> dict[str, dict]:
    """Object id -> attempts, held, distinct held, held and passed the six-direction test (``six``), the held grasps'
    start depths (``held_start_mm``: a list, mm inside the object) (all sources) and per source held / attempts."""
    from dexlite_pipeline.io.grasp_store import read_grasp_store

    grasps = read_grasp_store(out / "all_grasps.zarr")
    held = np.asarray(grasps.arrays["lift_success"], bool)
    six = held & np.asarray(grasps.arrays.get("six_dir_success", np.zeros(len(grasps), bool)), bool)
    start_mm = np.asarray(grasps.arrays.get("initial_penetration_mm", np.full(len(grasps), np.nan)), np.float64)
    labels = np.asarray(grasps.arrays["distinct_label"])
    sources = np.asarray(grasps.arrays["source"], dtype=object)
    rows = {}
    for object_id in sorted(set(grasps.object_id.tolist())):
        mine = grasps.object_id == object_id
        row = {"attempts": int(mine.sum()), "held": int(held[mine].sum()), "distinct": len(set(labels[mine & held].tolist())),
               "six": int(six[mine].sum()), "held_start_mm": start_mm[mine & held].tolist()}
        for source in ("model", "optimization"):
            part = mine & (sources == source)
            row[source] = f"{int(held[part].sum())}/{int(part.sum())}" if part.any() else "-"
        rows[object_id] = row
    return rows


def parse_seed_runs(argv: list[str] | None, description: str, mesh_sets: bool = False,
                    attempts: int | None = None) -> tuple[argparse.Namespace, list[str]]:
    """OUT_DIR, --seeds, --threads and --config-json (and --set with ``mesh_sets``, --n defaulting to ``attempts`` when
    given), and the arguments after ``--`` (for every ``dexlite grasp`` call)."""
    argv = sys.argv[1:] if argv is None else argv
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    own = argv[: argv.index("--")] if "--" in argv else argv
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--config-json", type=json.loads, default={}, metavar="JSON",
                        help='config sections for every call, e.g. \'{"sample": {"type_mix": "even"}}\' (the seed is --seeds\')')
    if mesh_sets:
        parser.add_argument("--set", dest="mesh_set", choices=("household", "kitchen"), default="household",
                            help="household: mug, bowl, wine bottle, cereal box and the mug in mm; kitchen: bowl, plate, spatula, hammer")
    if attempts is not None:
        parser.add_argument("--n", type=int, default=attempts, help=f"attempts per object and call (default {attempts})")
    return parser.parse_args(own), extra


def main(argv: list[str] | None = None) -> int:
    args, extra = parse_seed_runs(argv, __doc__.splitlines()[0], mesh_sets=True)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from make_household_meshes import write_check_meshes, write_kitchen_meshes

    meshes = args.out_dir / "meshes"
    if args.mesh_set == "kitchen":
        write_kitchen_meshes(meshes)
        calls = ((meshes, None, "metres"),)
    else:
        write_check_meshes(meshes, "m")
        calls = ((meshes, None, "metres"), (meshes / "mm", "mm", "mm"))
    lines = ["| seed | mesh | attempts | held | distinct held | model held | optimization held | command CPU-s | command wall s |",
             "| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]  # fmt: skip
    for seed in args.seeds:
        for folder, units, label in calls:
            out = args.out_dir / f"seed_{seed}" / label
            cpu, wall = run_grasp(str(folder), out, seed, args.threads, extra, units, args.config_json)
            for object_id, row in per_mesh_counts(out).items():
                name = object_id + (" (mm)" if units else "")
                lines.append(f"| {seed} | {name} | {row['attempts']} | {row['held']} | {row['distinct']} | {row['model']} | "
                             f"{row['optimization']} | {cpu:.0f} | {wall:.0f} |")  # fmt: skip
            print("\n".join(lines[-len(per_mesh_counts(out)):]), flush=True)
    table = "\n".join(lines) + "\n"
    (args.out_dir / "check_meshes.md").write_text(table)
    print(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
