"""DexGraspNet qpos <-> hand_pose conversion."""

import numpy as np
import pytest

from dexlite_pipeline.hand.qpos import QPOS_KEYS, QposError, hand_pose_from_qpos, qpos_from_hand_pose


def _qpos(seed=0):
    rng = np.random.default_rng(seed)
    return {k: float(v) for k, v in zip(QPOS_KEYS, rng.normal(size=len(QPOS_KEYS)))}


def test_round_trip_is_exact():
    qpos = _qpos()
    assert qpos_from_hand_pose(hand_pose_from_qpos(qpos)) == qpos


def test_float32_store_round_trip_within_float_precision():
    qpos = _qpos(1)
    back = qpos_from_hand_pose(hand_pose_from_qpos(qpos).astype(np.float32))
    for key in QPOS_KEYS:
        assert back[key] == pytest.approx(qpos[key], rel=1e-6, abs=1e-7)


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda q: q.pop("WRJRx"), "missing"),
        (lambda q: q.__setitem__("robot0:WRJ1", 0.0), "unknown"),
        (lambda q: q.__setitem__("robot0:FFJ0", float("nan")), "not finite"),
        (lambda q: q.__setitem__("robot0:FFJ0", "0.1"), "not a number"),
    ],
)
def test_bad_qpos_is_rejected_with_reason(edit, message):
    qpos = _qpos()
    edit(qpos)
    with pytest.raises(QposError, match=message):
        hand_pose_from_qpos(qpos)
