"""``dexlite export-dexgraspnet GRASPS.zarr --out OUT_DIR``: write a grasp store in DexGraspNet's layout.

``OUT_DIR/dataset/<object_id>.npy`` holds, per object, DexGraspNet's list of
``{'qpos': {...}, 'scale': s}`` dicts; with ``--objects DIR`` the convex pieces of each
object are written as ``OUT_DIR/meshdata/<object_id>/coacd/decomposed.obj`` too, so
DexGraspNet-based tools (and ``dexlite import-dexgraspnet``) can read the result whole.
An empty store is an error (exit status 2): there would be nothing to read.
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grasps", help="grasp store (.zarr)")
    parser.add_argument("--out", required=True, help="output folder (dataset/ and, with --objects, meshdata/)")
    parser.add_argument("--objects", action="append", default=[], help="prepared objects dir (repeatable): also export the meshes")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.io.dexgraspnet import export_dexgraspnet
    from dexlite_pipeline.io.grasp_store import read_grasp_store

    grasps = read_grasp_store(args.grasps)
    if not len(grasps):
        raise ValueError(f"{args.grasps}: the grasp store is empty, nothing to export")
    summary = export_dexgraspnet(grasps, args.out, args.objects or None)
    print(f"wrote {summary['grasps']} grasps of {summary['objects']} objects to {args.out}/dataset")
    if summary["missing_assets"]:
        print(f"no prepared asset (mesh not exported) for: {', '.join(summary['missing_assets'])}")
    return 0
