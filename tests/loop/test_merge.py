"""A round's merge on known cases: which new grasps join the set, and the candidates' reasons."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from dexlite_pipeline.evaluation.diversity import DiversityConfig, count_distinct_grasps
from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.loop.merge import candidate_counts, merge_round, new_distinct_grasps
from dexlite_pipeline.loop.round_basics import DROP_REASONS, DUPLICATE, LIFT_TEST
from dexlite_pipeline.loop.round_set import SET_ARRAYS

DIVERSITY = DiversityConfig()  # 2 cm, 30 degrees


def pose(x_m: float = 0.0, yaw_deg: float = 0.0) -> np.ndarray:
    """A hand pose with its palm at (x, 0, 0.1) m turned ``yaw_deg`` about z, joints 0."""
    out = np.zeros(28, np.float32)
    out[:3] = (x_m, 0.0, 0.1)
    out[3:6] = Rotation.from_euler("z", yaw_deg, degrees=True).as_euler("xyz")
    return out


def grasp_set(poses, objects, scale: float = 0.1, **extra) -> GraspSet:
    n = len(poses)
    arrays = {"hand_pose": np.asarray(poses, np.float32).reshape(n, 28), "object_id": np.asarray(objects, dtype=object),
              "scale": np.full(n, scale, np.float32), **extra}  # fmt: skip
    return GraspSet(arrays, {})


def test_a_new_grasp_near_a_known_one_is_not_new():
    known = [pose(0.0)]
    new = [pose(0.01), pose(0.05), pose(0.0, yaw_deg=90.0)]  # 1 cm away: the same; 5 cm away: new; turned 90 degrees: new
    kept = new_distinct_grasps(known, ["a"] * 1, new, ["a"] * 3, DIVERSITY)
    assert kept.tolist() == [False, True, True]


def test_new_grasps_are_compared_with_earlier_picks_of_the_round():
    new = [pose(0.05), pose(0.055), pose(0.1)]  # the second is the first again
    kept = new_distinct_grasps(np.zeros((0, 28)), np.zeros(0, dtype=object), new, ["a"] * 3, DIVERSITY)
    assert kept.tolist() == [True, False, True]


def test_grasps_of_other_objects_or_scales_never_match():
    kept = new_distinct_grasps([pose(0.0)], ["a|0.1"], [pose(0.0), pose(0.0)], ["b|0.1", "a|0.12"], DIVERSITY)
    assert kept.tolist() == [True, True]


def test_each_kept_grasp_adds_one_distinct_grasp_to_the_set():
    rng = np.random.default_rng(3)
    known = [pose(x, yaw) for x, yaw in zip(rng.uniform(0, 0.1, 12), rng.uniform(0, 180, 12))]
    new = [pose(x, yaw) for x, yaw in zip(rng.uniform(0, 0.1, 30), rng.uniform(0, 180, 30))]
    kept = new_distinct_grasps(known, ["a"] * 12, new, ["a"] * 30, DIVERSITY)
    merged = np.concatenate([np.asarray(known), np.asarray(new)[kept]])
    assert 0 < kept.sum() < 30
    assert count_distinct_grasps(merged) == count_distinct_grasps(np.asarray(known)) + int(kept.sum())


def test_merge_keeps_the_best_of_duplicates_and_records_every_reason():
    previous = grasp_set([pose(0.0)], ["a"], lift_success=np.ones(1, bool), contact_index=np.zeros((1, 4), np.int64), round=np.zeros(1, np.int64))
    shard = grasp_set(
        [pose(0.005), pose(0.06), pose(0.065), pose(0.2)], ["a", "a", "a", "b"],
        E_post=np.array([0.1, 0.5, 0.2, 0.3]), drop_reason=np.array(["", "", "", LIFT_TEST], dtype=object),
        contact_index=np.arange(16).reshape(4, 4),
    )
    merged, candidates = merge_round(previous, [shard], DIVERSITY, round_number=1)
    # row 0 repeats the known grasp; rows 1 and 2 are one grasp, row 2 has the lower E_post and is kept; row 3 failed the lift test
    assert candidates.arrays["drop_reason"].tolist() == [DUPLICATE, DUPLICATE, "", LIFT_TEST]
    assert set(merged.arrays) == set(SET_ARRAYS) and len(merged) == 2
    np.testing.assert_allclose(merged.hand_pose[1], pose(0.065))
    assert merged.arrays["round"].tolist() == [0, 1] and merged.arrays["contact_index"][1].tolist() == [8, 9, 10, 11]
    counts = candidate_counts(candidates).set_index("object_id")
    assert counts.loc["a", "sampled"] == 3 and counts.loc["a", "kept"] == 1 and counts.loc["a", DUPLICATE] == 2
    assert counts.loc["b", LIFT_TEST] == 1 and counts[list(DROP_REASONS)].sum().sum() + counts["kept"].sum() == counts["sampled"].sum()


def test_merge_without_candidates_keeps_the_set():
    previous = grasp_set([pose(0.0)], ["a"], lift_success=np.ones(1, bool), contact_index=np.zeros((1, 4), np.int64), round=np.zeros(1, np.int64))
    merged, candidates = merge_round(previous, [], DIVERSITY, round_number=2)
    assert len(merged) == 1 and len(candidates) == 0
