"""The learning curve's training subsets: seeded, nested, and all objects by default."""

from dexlite_pipeline.model.trainer import training_object_subset

OBJECTS = {f"obj-{i:03d}" for i in range(30)}


def test_subsets_are_seeded_and_nested():
    small, large = training_object_subset(OBJECTS, 5, seed=0), training_object_subset(OBJECTS, 12, seed=0)
    assert len(small) == 5 and len(large) == 12 and small < large
    assert training_object_subset(OBJECTS, 5, seed=0) == small
    assert training_object_subset(OBJECTS, 5, seed=1) != small


def test_zero_or_too_many_means_all():
    assert training_object_subset(OBJECTS, 0, seed=0) == OBJECTS
    assert training_object_subset(OBJECTS, 99, seed=3) == OBJECTS
