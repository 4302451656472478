"""Write the household check meshes for `dexlite grasp` checks.

    python benchmarks/experiments/make_household_meshes.py OUT_DIR               # metres, plus OUT_DIR/mm/mug.obj
    python benchmarks/experiments/make_household_meshes.py OUT_DIR --units mm    # all four in millimetres

Four objects at their real size, in no split (fixed parameters, not drawn from a seed; see
``objects.household.CHECK_OBJECTS``): ``mug.obj`` (9.5 cm tall, 4 mm wall, a handle),
``bowl.obj`` (16 cm across), ``wine_bottle.obj`` (30 cm tall) and ``cereal_box.obj``
(30 x 20 x 7 cm), upright (+z up, base on z = 0). With ``--units m`` (the default) the same mug
is also written in millimetres to ``OUT_DIR/mm/mug.obj``, in its own folder so that
``dexlite grasp OUT_DIR`` grasps only the metre meshes and ``dexlite grasp OUT_DIR/mm --units mm``
the millimetre one. Prints one line per file with its size.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

UNIT_SCALE = {"m": 1.0, "mm": 1000.0}


def write_check_meshes(out_dir: Path, units: str) -> list[tuple[Path, object]]:
    """Write the check meshes in ``units`` (and the millimetre mug when ``units`` is m); returns (path, mesh) pairs."""
    from dexlite_pipeline.objects.household import check_meshes, write_mesh_obj

    written = []
    meshes = check_meshes()
    for name, mesh in meshes.items():
        scaled = mesh.copy()
        scaled.apply_scale(UNIT_SCALE[units])
        path = out_dir / f"{name}.obj"
        write_mesh_obj(scaled, path)
        written.append((path, scaled))
    if units == "m":
        mug = meshes["mug"].copy()
        mug.apply_scale(UNIT_SCALE["mm"])
        path = out_dir / "mm" / "mug.obj"
        write_mesh_obj(mug, path)
        written.append((path, mug))
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out_dir", type=Path, help="folder to write the .obj files to (created if missing)")
    parser.add_argument("--units", choices=sorted(UNIT_SCALE), default="m", help="units of the written meshes (default: m)")
    args = parser.parse_args(argv)
    if args.out_dir.exists() and not args.out_dir.is_dir():
        print(f"make_household_meshes: error: {args.out_dir}: exists and is not a folder", file=sys.stderr)
        return 2
    for path, mesh in write_check_meshes(args.out_dir, args.units):
        unit = "mm" if path.parent.name == "mm" or args.units == "mm" else "m"
        extents = " x ".join(f"{v:g}" for v in mesh.extents.round(4))
        print(f"{path}: {extents} {unit} (x, y, z), volume {mesh.volume:.4g} {unit}^3")
    return 0


if __name__ == "__main__":
    sys.exit(main())
