"""`dexlite grasp` on one object in two forms of file: one closed shell against convex pieces or several shells.

    python benchmarks/experiments/grasp_mesh_forms.py OUT_DIR [--seeds 0 1 2] [--threads 1] [-- EXTRA dexlite grasp ARGS]

Writes, in metres (``dexlite_pipeline.objects.mesh_forms``): a can 8.4 cm wide and 12 cm tall as one shell and as
32 touching convex pieces; a 22 cm bottle as one shell and as three touching shells (body, shoulder and neck, cap);
the check mug as one shell and as CoACD's convex pieces (which fill part of its cavity: another solid, shown, not
compared). Per seed, one ``dexlite grasp`` call on the folder (arguments after ``--`` go to it, e.g.
``-- --min-distinct 0`` or ``-- --from-scratch``). Prints, and writes to ``OUT_DIR/mesh_forms.md``, per mesh and
seed: attempts, held, distinct held, and how the mesh was prepared (route and deviation from its file).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def write_forms(folder: Path) -> None:
    from dexlite_pipeline.objects import mesh_forms

    folder.mkdir(parents=True, exist_ok=True)
    pieces, can = mesh_forms.can_as_convex_pieces()
    shells, bottle = mesh_forms.three_shell_bottle()
    mug_pieces, mug = mesh_forms.mug_as_convex_pieces()
    for name, mesh in {"can_one_shell": can, "can_32_pieces": pieces, "bottle_one_shell": bottle, "bottle_three_shells": shells,
                       "mug_one_shell": mug, "mug_coacd_pieces": mug_pieces}.items():  # fmt: skip
        mesh.export(folder / f"{name}.obj")


def main(argv: list[str] | None = None) -> int:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from grasp_check_meshes import parse_seed_runs, per_mesh_counts, run_grasp

    args, extra = parse_seed_runs(argv, __doc__.splitlines()[0])

    meshes = args.out_dir / "meshes"
    if not meshes.is_dir():
        write_forms(meshes)
    lines = ["| seed | mesh | attempts | held | distinct held | command CPU-s | prepared as | prepared solid vs the file |",
             "| ---: | --- | ---: | ---: | ---: | ---: | --- | --- |"]  # fmt: skip
    for seed in args.seeds:
        out = args.out_dir / f"seed_{seed}"
        cpu, _ = run_grasp(str(meshes), out, seed, args.threads, extra, None, args.config_json)
        counts = per_mesh_counts(out)
        for object_id, row in counts.items():
            meta = json.loads((out / "objects" / "assets" / object_id / "meta.json").read_text())
            lines.append(f"| {seed} | {object_id} | {row['attempts']} | {row['held']} | {row['distinct']} | {cpu:.0f} | "
                         f"{meta['preparation']['summary']} | {meta['deviation']['summary']} |")  # fmt: skip
        print("\n".join(lines[-len(counts):]), flush=True)
    table = "\n".join(lines) + "\n"
    (args.out_dir / "mesh_forms.md").write_text(table)
    print(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
