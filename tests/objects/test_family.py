"""Object families read from ids: household families with their perturbed instances, procedural, other."""

import pytest

from dexlite_pipeline.objects.family import object_family


@pytest.mark.parametrize("object_id, family", [
    ("household-mug-040", "mug"), ("household-mug-040-p1", "mug"), ("household-cereal_box-003", "cereal_box"),
    ("household-toy_figure-011-p2", "toy_figure"), ("pb-random-007", "procedural"), ("my_scan", "other"),
    ("pb-duck", "other"), ("household-mug", "other"), ("household-mug-04x", "other"),
])
def test_family_of_each_kind_of_id(object_id, family):
    assert object_family(object_id) == family
