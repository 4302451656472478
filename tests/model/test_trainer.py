"""The learning curve's training subsets (objects, grasps per object): seeded, nested, and everything by default."""

import numpy as np

from dexlite_pipeline.model.trainer import grasps_per_object_subset, training_object_subset

OBJECTS = {f"obj-{i:03d}" for i in range(30)}


def test_subsets_are_seeded_and_nested():
    small, large = training_object_subset(OBJECTS, 5, seed=0), training_object_subset(OBJECTS, 12, seed=0)
    assert len(small) == 5 and len(large) == 12 and small < large
    assert training_object_subset(OBJECTS, 5, seed=0) == small
    assert training_object_subset(OBJECTS, 5, seed=1) != small


def test_zero_or_too_many_means_all():
    assert training_object_subset(OBJECTS, 0, seed=0) == OBJECTS
    assert training_object_subset(OBJECTS, 99, seed=3) == OBJECTS


def test_grasps_per_object_are_capped_seeded_and_nested():
    ids = np.array(["a"] * 10 + ["b"] * 3 + ["c"] * 7)[np.random.default_rng(5).permutation(20)]
    small, large = grasps_per_object_subset(ids, 2, seed=0), grasps_per_object_subset(ids, 5, seed=0)
    assert {o: int((ids[small] == o).sum()) for o in "abc"} == {"a": 2, "b": 2, "c": 2}
    assert {o: int((ids[large] == o).sum()) for o in "abc"} == {"a": 5, "b": 3, "c": 5}
    assert set(small.tolist()) < set(large.tolist()) and list(small) == sorted(small)
    assert np.array_equal(grasps_per_object_subset(ids, 2, seed=0), small)
    assert not np.array_equal(grasps_per_object_subset(ids, 2, seed=1), small)
    assert np.array_equal(grasps_per_object_subset(ids, 0, seed=0), np.arange(20))
