"""benchmarks/experiments/yaw_sensitivity.py: split objects grouped by family (perturbed apart), per form; the seeded yaws."""

import numpy as np
import pytest


def _row(object_id, family, form, held, distinct=1):
    return {"seed": 0, "object_id": object_id, "family": family, "form": form, "yaw_deg": 0.0, "attempts": 4, "held": held,
            "distinct": distinct, "six": held // 2, "held_start_mm": [0.4 * k for k in range(1, held + 1)]}


def test_families_of_the_shapes_split_and_tables_of_one_form(benchmark_script):
    script = benchmark_script("yaw_sensitivity")
    assert script.family_of("household-kettle-900") == "kettle"
    assert script.family_of("household-mug-900-p1") == "mug (perturbed)"
    rows = [_row("household-kettle-900", "kettle", "turned", 1), _row("household-mug-900-p1", "mug (perturbed)", "turned", 3, 2)]
    lines = script.family_table(rows, False, ("turned",))
    assert lines[0] == ("| family | objects | turned: held / attempts | turned: six directions | turned: distinct / object | turned: "
                        "start depth of held, median mm |")
    assert lines[2] == "| kettle | 1 | 1/4 = 25.0% | 0.0% | 1.00 | 0.40 |"
    assert lines[3] == "| mug (perturbed) | 1 | 3/4 = 75.0% | 25.0% | 2.00 | 0.80 |"
    assert lines[4] == "| **all objects** | 2 | 4/8 = 50.0% | 12.5% | 1.50 | 0.60 |"  # depths 0.4 | 0.4, 0.8, 1.2
    both = script.family_table(rows, False)  # the default: generated and turned; a form without rows shows '-'
    assert both[2].startswith("| kettle | 1 | - | - | - | - | 1/4 = 25.0%")


def test_yaws_are_seeded_per_object_and_seed(benchmark_script):
    script = benchmark_script("yaw_sensitivity")
    first = script.yaws_of("household-mug-900", 0, 2)
    assert np.array_equal(first, script.yaws_of("household-mug-900", 0, 2)) and np.all((first >= 0) & (first < 2 * np.pi))
    assert not np.array_equal(first, script.yaws_of("household-mug-900", 1, 2))
    assert not np.array_equal(first, script.yaws_of("household-mug-901", 0, 2))


def test_the_benchmark_split_is_its_procedural_objects_as_their_urdf_places_them(benchmark_script):
    script = benchmark_script("yaw_sensitivity")
    from dexlite_pipeline.objects.asset_building import load_source_mesh
    from dexlite_pipeline.objects.sources import benchmark_object_list, pybullet_random_source_of

    meshes = script.split_meshes("benchmark", 2)
    assert list(meshes) == benchmark_object_list()[:2]
    assert all(script.family_of(object_id) == "procedural" for object_id in meshes)
    placed = load_source_mesh(pybullet_random_source_of(benchmark_object_list()[0]))
    assert np.allclose(meshes[benchmark_object_list()[0]].vertices, placed.vertices)


def test_objects_given_by_id_are_placed_by_their_kind(benchmark_script):
    script = benchmark_script("yaw_sensitivity")
    assert script.objects_kind(["pb-random-801", "pb-random-802"]) == "benchmark"
    assert script.objects_kind(["household-mug-800"]) == "household"
    with pytest.raises(ValueError, match="not both"):
        script.objects_kind(["pb-random-801", "household-mug-800"])
    meshes = script.split_meshes("household", None, ["household-mug-800"])
    assert list(meshes) == ["household-mug-800"] and meshes["household-mug-800"].is_watertight
