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


def store_hand_model(grasps_path: str, device="cpu") -> tuple[object, dict]:
    """(hand model on ``device``, its record) of the hand a grasp store records (``io.grasp_store.store_hand``; the
    Shadow Hand for a store without one): the commands test, score and draw a store's grasps with their own hand. A
    hand file that is gone, unusable or changed since the store was written is refused in one line (``ValueError``)."""
    from dexlite_pipeline.hand.choice import hand_record, resolve_hand
    from dexlite_pipeline.io.grasp_store import check_one_hand, read_grasp_store, store_hand

    attrs = read_grasp_store(grasps_path).attrs
    hand = store_hand(attrs)
    record = hand_record(hand)
    check_one_hand([(f"the hand file {hand}", record), (str(grasps_path), attrs)])
    return resolve_hand(hand, device), record
