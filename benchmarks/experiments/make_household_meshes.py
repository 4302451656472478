"""Write the household check meshes for `dexlite grasp` checks.

    python benchmarks/experiments/make_household_meshes.py OUT_DIR               # metres, plus OUT_DIR/mm/mug.obj
    python benchmarks/experiments/make_household_meshes.py OUT_DIR --units mm    # all four in millimetres
    python benchmarks/experiments/make_household_meshes.py OUT_DIR --set kitchen # bowl, plate, spatula, hammer (metres)

Four objects at their real size, in no split (fixed parameters, not drawn from a seed; see
``objects.household.CHECK_OBJECTS``): ``mug.obj`` (9.5 cm tall, 4 mm wall, a handle),
``bowl.obj`` (16 cm across), ``wine_bottle.obj`` (30 cm tall) and ``cereal_box.obj``
(30 x 20 x 7 cm), upright (+z up, base on z = 0). With ``--units m`` (the default) the same mug
is also written in millimetres to ``OUT_DIR/mm/mug.obj``, in its own folder so that
``dexlite grasp OUT_DIR`` grasps only the metre meshes and ``dexlite grasp OUT_DIR/mm --units mm``
the millimetre one. Prints one line per file with its size.

``--set kitchen``: the objects grasp types are for, at their real size and in no split (fixed parameters below,
typical of each family's range): ``bowl.obj`` (the check bowl: 16 cm across, 4 mm wall), ``plate.obj`` (a 26 cm
dinner plate, 4 mm thick), ``spatula.obj`` (lying flat: 19 cm handle, 9.5 x 7 cm blade 5 mm thick) and
``hammer.obj`` (lying on its side: 28 cm handle, 11.5 cm head).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

UNIT_SCALE = {"m": 1.0, "mm": 1000.0}

# name -> (household family, its builder's parameters in metres): fixed, so no seeded draw of any split makes them
KITCHEN_OBJECTS: dict[str, tuple[str, dict]] = {
    "plate": ("plate", {"height": 0.024, "rim_radius": 0.13, "base_radius": 0.08, "wall": 0.004, "base_thickness": 0.0045,
                        "roundness": 0.35}),
    "spatula": ("spatula", {"handle_length": 0.19, "handle_radius": 0.011, "blade_length": 0.095, "blade_width": 0.07,
                            "blade_thickness": 0.005}),
    "hammer": ("hammer", {"handle_length": 0.28, "handle_radius": 0.014, "head_length": 0.115, "head_section": 0.028}),
}
MESH_SETS = ("household", "kitchen")


def kitchen_meshes() -> dict[str, object]:
    """The kitchen check meshes by name (metres): the check bowl (4 mm wall), a plate, a spatula and a hammer."""
    from dexlite_pipeline.objects.household import build_family, check_meshes

    return {"bowl": check_meshes()["bowl"], **{name: build_family(family, params) for name, (family, params) in KITCHEN_OBJECTS.items()}}


def write_kitchen_meshes(out_dir: Path) -> list[tuple[Path, object]]:
    """Write the kitchen check meshes in metres to ``out_dir``; returns (path, mesh) pairs."""
    from dexlite_pipeline.objects.household import write_mesh_obj

    written = []
    for name, mesh in kitchen_meshes().items():
        path = out_dir / f"{name}.obj"
        write_mesh_obj(mesh, path)
        written.append((path, mesh))
    return written


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
    parser.add_argument("--set", dest="mesh_set", choices=MESH_SETS, default="household",
                        help="household: mug, bowl, wine bottle, cereal box; kitchen: bowl, plate, spatula, hammer (metres only)")
    args = parser.parse_args(argv)
    if args.mesh_set == "kitchen" and args.units != "m":
        print("make_household_meshes: error: --set kitchen is written in metres only (no --units)", file=sys.stderr)
        return 2
    if args.out_dir.exists() and not args.out_dir.is_dir():
        print(f"make_household_meshes: error: {args.out_dir}: exists and is not a folder", file=sys.stderr)
        return 2
    written = write_kitchen_meshes(args.out_dir) if args.mesh_set == "kitchen" else write_check_meshes(args.out_dir, args.units)
    for path, mesh in written:
        unit = "mm" if path.parent.name == "mm" or args.units == "mm" else "m"
        extents = " x ".join(f"{v:g}" for v in mesh.extents.round(4))
        print(f"{path}: {extents} {unit} (x, y, z), volume {mesh.volume:.4g} {unit}^3")
    return 0


if __name__ == "__main__":
    sys.exit(main())
