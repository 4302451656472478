"""The learning curves' training subsets (families, objects, grasps per object): seeded, nested, and everything by default."""

import numpy as np

from dexlite_pipeline.model.trainer import grasps_per_object_subset, training_family_subset, training_object_subset

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


FAMILY_OBJECTS = ({f"household-{family}-{i:03d}" for family in ("mug", "bowl", "hammer", "plate", "spoon") for i in range(4)}
                  | {"household-mug-001-p1", "pb-random-007", "pb-random-012", "my_scan"})


def families_of(ids: set[str]) -> set[str]:
    return {"procedural" if i.startswith("pb-") else "other" if i == "my_scan" else i.split("-")[1] for i in ids}


def test_family_subsets_take_whole_families_seeded_and_nested():
    small, large = training_family_subset(FAMILY_OBJECTS, 2, seed=0), training_family_subset(FAMILY_OBJECTS, 5, seed=0)
    assert len(families_of(small)) == 2 and len(families_of(large)) == 5 and small < large
    for family in families_of(large):  # every object of a chosen family, its perturbed instances with it
        assert {i for i in FAMILY_OBJECTS if families_of({i}) == {family}} <= large
    assert "household-mug-001-p1" in large or "mug" not in families_of(large)
    assert training_family_subset(FAMILY_OBJECTS, 2, seed=0) == small
    assert any(training_family_subset(FAMILY_OBJECTS, 2, seed=s) != small for s in (1, 2, 3))
    assert training_family_subset(FAMILY_OBJECTS, 0, seed=0) == FAMILY_OBJECTS == training_family_subset(FAMILY_OBJECTS, 7, seed=0)
