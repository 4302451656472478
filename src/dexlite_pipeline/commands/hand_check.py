"""``dexlite hand-check HAND``: what the pipeline derives from a hand's MJCF, and its FK checked against MuJoCo.

HAND is ``shadow``, ``allegro``, ``leap`` or the path of an MJCF file. It prints the links and
fingers, the joints with limits and actuators, the collision shapes, the contact candidates per
link, the palm frame, the pre-grasp and the grasp types it offers (``docs/hands.md`` says where each comes from), then
the largest FK disagreement with MuJoCo over random joint vectors; ``--picture FILE.png``
draws the collision surfaces, contact candidates and approach direction. Exit status: 0 when the
hand is usable and its FK agrees, 1 when FK disagrees, 2 (one line saying why) for a file
that cannot describe a hand.
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("hand", help="shadow, allegro, leap, or the path of a hand's MJCF file (.xml)")
    parser.add_argument("--vectors", type=int, default=64, help="random joint vectors of the FK check (default 64)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the random joint vectors")
    parser.add_argument("--picture", default=None, help="also write a PNG of the collision surfaces, contact candidates and approach direction")


def grasp_type_lines(name: str, description) -> list[str]:
    """The grasp types the hand offers: the Shadow Hand's written templates, or those derived from the description
    (``optim.described_types``: the fit takes 10-20 s per hand)."""
    from dexlite_pipeline.hand.choice import SHADOW

    if name == SHADOW:
        from dexlite_pipeline.optim.grasp_types import TYPE_NAMES

        return [f"grasp types: {', '.join(TYPE_NAMES)} (the Shadow Hand's written templates, optim/grasp_types.py)"]
    import torch

    from dexlite_pipeline.hand.described import DescribedHand
    from dexlite_pipeline.optim.described_types import type_report_lines

    return type_report_lines(DescribedHand(description, dtype=torch.float64))  # the fit's precision: built once


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.hand.check import kinematics_errors, random_joint_vectors, report_lines
    from dexlite_pipeline.hand.description import HandDescriptionError, hand_description

    if args.vectors < 1:
        raise ValueError("--vectors must be at least 1")
    try:
        description = hand_description(args.hand)
    except HandDescriptionError as exc:
        raise ValueError(f"{args.hand}: {exc}") from None
    errors = kinematics_errors(description, random_joint_vectors(description, args.vectors, args.seed))
    lines = report_lines(description, errors)
    print("\n".join([*lines[:-1], *grasp_type_lines(args.hand, description), lines[-1]]))  # the FK verdict last
    if args.picture:
        from dexlite_pipeline.report.hand_picture import hand_picture_png

        hand_picture_png(description, args.picture)
        print(f"wrote {args.picture}")
    return 0 if errors.ok else 1
