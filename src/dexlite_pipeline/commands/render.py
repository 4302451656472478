"""``dexlite render GRASPS.zarr --objects DIR --index K --out FILE.png``: picture of one grasp."""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grasps", help="grasp store (.zarr)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir (repeatable)")
    parser.add_argument("--index", type=int, default=0, help="row of the grasp to render (0-based)")
    parser.add_argument("--out", required=True, help="output PNG file")
    parser.add_argument("--size-px", type=int, default=400, help="height of each view in pixels")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.report.render import render_store_row

    render_store_row(args.grasps, args.index, args.objects, args.out, args.size_px)
    print(f"wrote {args.out}")
    return 0
