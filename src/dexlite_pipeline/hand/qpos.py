"""Lossless conversion between DexGraspNet ``qpos`` dicts and the 28-d ``hand_pose``."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from dexlite_pipeline.hand.model import JOINT_NAMES

TRANSLATION_KEYS = ("WRJTx", "WRJTy", "WRJTz")
ROTATION_KEYS = ("WRJRx", "WRJRy", "WRJRz")
QPOS_KEYS = TRANSLATION_KEYS + ROTATION_KEYS + JOINT_NAMES


class QposError(ValueError):
    """A qpos dict that cannot be converted (missing or unknown keys, non-finite values)."""


def hand_pose_from_qpos(qpos: Mapping[str, float]) -> np.ndarray:
    """DexGraspNet qpos dict -> float64 (28,) [t, static-xyz Euler, 22 joints]."""
    missing = [k for k in QPOS_KEYS if k not in qpos]
    if missing:
        raise QposError(f"missing qpos keys: {', '.join(missing)}")
    unknown = sorted(set(qpos) - set(QPOS_KEYS))
    if unknown:
        raise QposError(f"unknown qpos keys: {', '.join(unknown)}")
    values = []
    for key in QPOS_KEYS:
        value = qpos[key]
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise QposError(f"qpos[{key!r}] is {type(value).__name__}, not a number")
        if not math.isfinite(float(value)):
            raise QposError(f"qpos[{key!r}] is not finite ({value})")
        values.append(float(value))
    return np.asarray(values, dtype=np.float64)


def qpos_from_hand_pose(hand_pose: np.ndarray) -> dict[str, float]:
    """(28,) hand_pose -> DexGraspNet qpos dict (plain Python floats)."""
    pose = np.asarray(hand_pose, dtype=np.float64).reshape(-1)
    if pose.shape != (len(QPOS_KEYS),):
        raise QposError(f"hand_pose has {pose.size} values, expected {len(QPOS_KEYS)}")
    return {key: float(v) for key, v in zip(QPOS_KEYS, pose)}
