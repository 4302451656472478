"""``dexlite render GRASPS.zarr --index K --out FILE.png [--objects DIR]``: picture of one grasp.

``--objects`` defaults to the ``objects/`` folder beside the store (a ``dexlite grasp`` output folder). The hand drawn is
the store's (attribute ``hand``; a hand from its MJCF as its collision shapes, ``report.render``).
"""

from __future__ import annotations

import argparse

from dexlite_pipeline.commands import add_objects_argument, objects_dirs


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grasps", help="grasp store (.zarr)")
    add_objects_argument(parser)
    parser.add_argument("--index", type=int, default=0, help="row of the grasp to render (0-based)")
    parser.add_argument("--out", required=True, help="output PNG file")
    parser.add_argument("--size-px", type=int, default=400, help="height of each view in pixels")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.report.render import render_store_row

    objects = objects_dirs(args)
    render_store_row(args.grasps, args.index, objects, args.out, args.size_px)
    print(f"wrote {args.out}")
    return 0
