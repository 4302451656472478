"""The hand's part of the DexGraspNet-layout export (``io.dexgraspnet.export_dexgraspnet``) for a store of a hand other
than the Shadow Hand: ``qpos`` dicts with the hand's joint names and ``hand.json`` recording the hand."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from dexlite_pipeline.atomic import atomic_path
from dexlite_pipeline.hand.qpos import ROTATION_KEYS, TRANSLATION_KEYS

HAND_RECORD_NAME = "hand.json"


def hand_qpos(hand_pose: np.ndarray, joint_names: list[str]) -> dict[str, float]:
    """A (6 + J,) pose as a qpos dict: the joints by their MJCF names (rad), then the palm's ``WRJRx/y/z`` (xyz Euler,
    rad) and ``WRJTx/y/z`` (m), the keys and order of the Shadow Hand's export."""
    pose = [float(v) for v in np.asarray(hand_pose, np.float64).reshape(-1)]
    return {**dict(zip(joint_names, pose[6:])), **dict(zip(ROTATION_KEYS, pose[3:6])), **dict(zip(TRANSLATION_KEYS, pose[:3]))}


def write_hand_record(out_dir: Path, attrs: dict, hand: str, joint_names: list[str]) -> None:
    """``OUT_DIR/hand.json``: the hand (``hand``, ``hand_sha256`` for a file), its ``joint_names`` and the qpos keys."""
    record = {"hand": hand, **({"hand_sha256": attrs["hand_sha256"]} if attrs.get("hand_sha256") else {}), "joint_names": joint_names,
              "qpos": "the joints by these names (rad), WRJRx/y/z (xyz Euler, rad), WRJTx/y/z (m)"}
    with atomic_path(Path(out_dir) / HAND_RECORD_NAME) as tmp:
        tmp.write_text(json.dumps(record, indent=1) + "\n")
