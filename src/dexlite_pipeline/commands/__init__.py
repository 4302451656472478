"""The user tools' commands (``dexlite energy``, ``lift-test``, ``render``, ``export-dexgraspnet``,
``grasp``): thin argument adapters over the library, as ``stages`` is for the pipeline's stages."""

from __future__ import annotations

import argparse
from pathlib import Path

# The prepared objects of a `dexlite grasp` output folder DIR: DIR/objects beside DIR/grasps.zarr.
OBJECTS_BESIDE_STORE = "objects"


def add_objects_argument(parser: argparse.ArgumentParser, purpose: str = "") -> None:
    """``--objects DIR`` (repeatable), optional: by default the ``objects/`` folder beside the grasp store."""
    parser.add_argument("--objects", action="append", default=[],
                        help=f"prepared objects dir (repeatable; default: the {OBJECTS_BESIDE_STORE}/ folder beside the grasp store, "
                             f"as in a `dexlite grasp` output folder){purpose}")  # fmt: skip


def objects_dirs(args: argparse.Namespace) -> list[str]:
    """The ``--objects`` folders given, else the ``objects/`` folder beside ``args.grasps``; a one-line error when neither."""
    if args.objects:
        return list(args.objects)
    beside = Path(args.grasps).parent / OBJECTS_BESIDE_STORE
    if (beside / "assets").is_dir():
        return [str(beside)]
    raise ValueError(f"{args.grasps}: no --objects given and no prepared objects at {beside} (give --objects DIR)")


def refuse_other_hand_store(grasps_path: str, command: str) -> None:
    """A one-line ValueError when the store at ``grasps_path`` holds another hand's grasps than the Shadow Hand's, for a
    command that draws or scores the Shadow Hand only for now (``io.grasp_store.store_hand``; docs/hands.md)."""
    from dexlite_pipeline.io.grasp_store import DEFAULT_HAND, read_grasp_store, store_hand

    hand = store_hand(read_grasp_store(grasps_path).attrs)
    if hand != DEFAULT_HAND:
        raise ValueError(f"{grasps_path}: hand {hand}: dexlite {command} knows the Shadow Hand only, for now")
