"""Household objects: closed single solids at real size, seeded, their split held out, accepted by preparation."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh
import yaml

from dexlite_pipeline.config import ConfigError, from_section, validate_config
from dexlite_pipeline.objects import household as hh
from dexlite_pipeline.objects.prepare import ObjectsConfig
from dexlite_pipeline.objects.sources import (
    HOUSEHOLD_SPLIT_FILE,
    ObjectSourceError,
    benchmark_object_ids,
    collect_sources,
    household_benchmark_list,
)

INSTANCES = range(4)
# family -> (smallest, largest) bounding-box extent (m) an instance may have: real objects of that kind.
EXTENT_RANGES = {
    "mug": ((0.07, 0.12), (0.10, 0.14)),
    "cup": ((0.06, 0.09), (0.085, 0.14)),
    "bowl": ((0.03, 0.08), (0.12, 0.19)),
    "bottle": ((0.05, 0.08), (0.19, 0.26)),
    "wine_bottle": ((0.07, 0.08), (0.29, 0.31)),
    "can": ((0.05, 0.07), (0.095, 0.125)),
    "jar": ((0.06, 0.10), (0.075, 0.14)),
    "cereal_box": ((0.06, 0.08), (0.28, 0.32)),
    "box": ((0.035, 0.08), (0.10, 0.22)),
    "milk_carton": ((0.065, 0.095), (0.18, 0.25)),
    "hammer": ((0.024, 0.032), (0.25, 0.32)),
    "spatula": ((0.018, 0.026), (0.22, 0.31)),  # lying flat: its handle is the thickest part
}


def test_every_family_has_its_size_range():
    assert set(EXTENT_RANGES) == set(hh.FAMILIES)


@pytest.mark.parametrize("family", sorted(hh.FAMILIES))
def test_instances_are_single_closed_solids_at_real_size_standing_on_z0(family):
    heights = []
    for index in INSTANCES:
        obj = hh.household_object(hh.household_id(family, index))
        mesh = obj.mesh
        assert mesh.is_watertight and mesh.is_winding_consistent, obj.object_id
        assert mesh.body_count == 1 and mesh.volume > 0, obj.object_id
        assert mesh.bounds[0][2] == pytest.approx(0.0, abs=1e-12)  # resting on the table plane
        (low_min, low_max), (high_min, high_max) = EXTENT_RANGES[family]
        extents = np.sort(mesh.extents)
        assert low_min <= extents[0] <= low_max and high_min <= extents[2] <= high_max, (obj.object_id, extents)
        assert obj.real_radius_m == pytest.approx(np.linalg.norm(mesh.vertices - mesh.bounds.mean(axis=0), axis=1).max())
        heights.append(mesh.extents[2])
    assert np.ptp(heights) > 1e-3, "instances of a family must differ"


def test_many_instances_of_every_family_are_single_closed_solids():
    """Parameter draws near the ends of their ranges must still make closed solids (generation checks each)."""
    for family in hh.FAMILIES:
        for index in range(40):
            mesh = hh.household_object(hh.household_id(family, index)).mesh
            assert mesh.is_watertight and mesh.body_count == 1 and mesh.volume > 0


def _wall_thickness_at(mesh, z: float) -> float:
    """Outer minus inner radius of the wall loops (circles about the z axis) of the section at height z."""
    section = mesh.section(plane_origin=[0.0, 0.0, z], plane_normal=[0.0, 0.0, 1.0])
    radii = [np.linalg.norm(loop[:, :2], axis=1) for loop in section.discrete]
    radii = [r.mean() for r in radii if np.ptp(r) < 1e-3]
    assert len(radii) == 2, radii
    return max(radii) - min(radii)


@pytest.mark.parametrize("family", ["mug", "cup"])
def test_cup_walls_are_3_to_5_mm_as_drawn(family):
    for index in INSTANCES:
        obj = hh.household_object(hh.household_id(family, index))
        wall = obj.params["wall"]
        assert 0.003 <= wall <= 0.005
        # horizontal thickness of a wall tilted by at most ~10 degrees: wall / cos(tilt)
        assert _wall_thickness_at(obj.mesh, obj.params["height"] * 0.5) == pytest.approx(wall, rel=0.03)  # between the handle ends


def test_mug_handle_is_one_body_with_the_cup_and_leaves_room_for_fingers():
    mug = hh.build_family(*hh.CHECK_OBJECTS["mug"])
    params = hh.CHECK_OBJECTS["mug"][1]
    assert params["wall"] == 0.004 and mug.body_count == 1
    # The handle reaches out beyond the wall on +x only, and there is a hole between it and the wall.
    assert mug.bounds[1][0] > params["rim_radius"] + params["handle_reach"]
    assert mug.bounds[0][0] == pytest.approx(-params["rim_radius"], abs=1e-4)  # the wider rim, on the side without a handle
    gap = [params["rim_radius"] + params["handle_reach"] / 2, 0.0, params["height"] * 0.5]
    assert not mug.contains([gap])[0]
    assert mug.euler_number == 0  # genus 1: the handle is a loop, not a lump


def test_check_meshes_are_the_sizes_the_checks_name():
    meshes = hh.check_meshes()
    assert set(meshes) == {"mug", "bowl", "wine_bottle", "cereal_box"}
    assert meshes["wine_bottle"].extents[2] == pytest.approx(0.30)
    assert np.sort(meshes["cereal_box"].extents) == pytest.approx([0.07, 0.20, 0.30])
    assert 0.12 <= meshes["bowl"].extents[0] <= 0.2


def test_an_id_always_means_the_same_object_and_ids_differ():
    first = hh.household_object("household-mug-003")
    again = hh.household_object("household-mug-003")
    assert first.params == again.params
    assert first.mesh.export(file_type="obj") == again.mesh.export(file_type="obj")
    other = hh.household_object("household-mug-004")
    assert other.params != first.params


@pytest.mark.parametrize("bad", ["pb-random-001", "household-teapot-001", "household-mug-x", "household-mug"])
def test_bad_ids_are_named_in_the_error(bad):
    with pytest.raises(ValueError, match=bad):
        hh.parse_household_id(bad)


def test_household_split_is_recorded_covers_every_family_and_is_never_trained_on():
    ids = household_benchmark_list()
    record = yaml.safe_load(HOUSEHOLD_SPLIT_FILE.read_text())
    assert len(ids) >= 24 and len(set(ids)) == len(ids) and record["rule"]
    assert {hh.parse_household_id(i)[0] for i in ids} == set(hh.FAMILIES)
    assert not set(ids) & benchmark_object_ids()
    # Training draws of any size skip the split (12 families x 1000 instances reach past its 900s).
    training = hh.training_household_ids(12 * 1000, frozenset(ids))
    assert len(training) == 12 * 1000 == len(set(training)) and not set(training) & set(ids)
    assert hh.training_household_ids(12, frozenset(ids)) == [hh.household_id(f, 0) for f in hh.FAMILIES]


def test_collect_sources_adds_household_objects_written_in_metres(tmp_path):
    folder = tmp_path / "household_meshes"
    (tmp_path / "household_meshes").mkdir()
    (folder / "household-jar-777.obj").write_text("stale\n")
    sources = collect_sources(0, [], [], seed=0, household_count=3, household_benchmark_objects=2, household_dir=folder)
    split = household_benchmark_list()
    assert [s.object_id for s in sources] == ["household-mug-000", "household-bowl-000", "household-bottle-000", *split[:2]]
    assert [s.always_heldout for s in sources] == [False, False, False, True, True]
    assert sorted(p.name for p in folder.iterdir()) == sorted(f"{s.object_id}.obj" for s in sources)  # the stale file is gone
    for source in sources:
        loaded = trimesh.load(source.file, force="mesh")
        expected = hh.household_object(source.object_id)
        assert loaded.extents == pytest.approx(expected.mesh.extents, abs=1e-7)  # metres, as generated
        assert source.real_radius_m == pytest.approx(expected.real_radius_m)
    # None asked: nothing is generated, no folder needed.
    assert collect_sources(0, [], [], seed=0) == []


def test_household_first_takes_the_next_objects_of_the_same_order(tmp_path):
    """Campaign batches: objects [first, first + count) of the round-robin order, so consecutive batches tile it."""
    whole = collect_sources(0, [], [], seed=0, household_count=7, household_dir=tmp_path / "whole")
    first = collect_sources(0, [], [], seed=0, household_count=4, household_dir=tmp_path / "a")
    rest = collect_sources(0, [], [], seed=0, household_count=3, household_first=4, household_dir=tmp_path / "b")
    assert [s.object_id for s in first + rest] == [s.object_id for s in whole]
    assert not {s.object_id for s in whole} & set(household_benchmark_list())


def test_household_families_draws_round_robin_over_the_named_families_only(tmp_path):
    """A campaign batch for some families: the same ids (so the same objects) as in the whole order, in the given
    family order, never the household split; an unknown family is refused naming the key."""
    drawn = collect_sources(0, [], [], seed=0, household_count=5, household_families=("spatula", "bowl"), household_dir=tmp_path / "a")
    assert [s.object_id for s in drawn] == ["household-spatula-000", "household-bowl-000", "household-spatula-001",
                                            "household-bowl-001", "household-spatula-002"]
    later = collect_sources(0, [], [], seed=0, household_count=2, household_first=4, household_families=("spatula", "bowl"),
                            household_dir=tmp_path / "b")
    assert [s.object_id for s in later] == ["household-spatula-002", "household-bowl-002"]
    with pytest.raises(ObjectSourceError, match="objects.household_families: unknown household families 'teapot'"):
        collect_sources(0, [], [], seed=0, household_count=1, household_families=("teapot",), household_dir=tmp_path / "c")


def test_household_source_errors_name_the_key(tmp_path):
    with pytest.raises(ObjectSourceError, match="objects.household_benchmark_objects"):
        collect_sources(0, [], [], seed=0, household_benchmark_objects=len(household_benchmark_list()) + 1, household_dir=tmp_path)
    with pytest.raises(ObjectSourceError, match="household_count"):
        collect_sources(0, [], [], seed=0, household_count=1)


def test_config_keys_validate():
    section = {"builtin_count": 0, "mesh_dirs": [], "heldout_mesh_dirs": [], "household_count": 5, "household_benchmark_objects": 24}
    config = {"seed": 0, "device": "cpu", "shards": 1, "objects": section, "dexgraspnet": {"root": ""}}
    validate_config(config)
    built = from_section(ObjectsConfig, section, "config.objects")
    assert (built.household_count, built.household_benchmark_objects) == (5, 24)
    assert (ObjectsConfig().household_count, ObjectsConfig().household_benchmark_objects) == (0, 0)  # the default run is unchanged
    for key in ("household_count", "household_benchmark_objects"):
        with pytest.raises(ConfigError, match=key):
            validate_config({**config, "objects": {**section, key: -1}})


def test_household_objects_pass_preparation_and_the_stability_test(tmp_path):
    """Two training objects (a 3-5 mm walled mug, a bowl) and one of the split, through the prepare-objects
    stage with small grids, then the table test at the default settings."""
    from dexlite_pipeline.cli import main
    from dexlite_pipeline.objects.assets import read_catalog
    from dexlite_pipeline.objects.stability import StabilityConfig, stability_filter

    out = tmp_path / "objects"
    objects = {"builtin_count": 0, "benchmark_objects": 0, "household_count": 2, "household_benchmark_objects": 1,
               "sdf_resolution": 32, "surface_points": 256, "coacd_max_convex_hull": 4,
               # CoACD's search is nearly all of the cost: the least effort it allows here (acceptance, not quality)
               "coacd_mcts_iterations": 10, "coacd_mcts_nodes": 5, "coacd_mcts_max_depth": 1, "coacd_resolution": 300}
    cfg = json.dumps({"seed": 0, "objects": objects})
    assert main(["prepare-objects", "--config-json", cfg, "--catalog", str(out / "catalog.parquet"),
                 "--record", str(out / "prepare_config.json"), "--threads", "1"]) == 0
    catalog = read_catalog(out).set_index("object_id")
    first_split = household_benchmark_list()[0]
    assert list(catalog.index) == sorted(["household-bowl-000", "household-mug-000", first_split])
    assert (catalog["status"] == "ok").all(), catalog["reason"].to_dict()
    assert catalog.loc[first_split, "split"] == "heldout"
    for object_id in catalog.index:
        meta = json.loads((out / "assets" / object_id / "meta.json").read_text())
        real = hh.household_object(object_id).real_radius_m
        # the mesh was in metres: normalized x (1 / factor) is the real object, radius x 1.03; the held-out one was turned
        # about z (objects.heldout_yaw), which moves its bounding box's centre and so its radius, by a few percent at most
        assert 1.0 / meta["normalization_factor"] == pytest.approx(meta["real_radius_m"] * 1.03, rel=1e-4)
        turned = catalog.loc[object_id, "turn_deg"] != 0
        assert turned == (object_id == first_split) and meta["turned_about_z_deg"] == catalog.loc[object_id, "turn_deg"]
        assert meta["real_radius_m"] == pytest.approx(real, rel=0.1 if turned else 1e-9)
    table = stability_filter([str(out)], 0, StabilityConfig(), 1)
    assert table["stable"].all(), table.to_dict("records")


def test_renaming_clashing_ids_keeps_the_real_radius():
    from dexlite_pipeline.objects.sources import MeshSource, make_ids_unique

    clashing = [MeshSource("user-mug", "user", f"/tmp/{d}/mug.obj", real_radius_m=0.08) for d in ("a", "b")]
    renamed = make_ids_unique(clashing)
    assert len({s.object_id for s in renamed}) == 2 and all(s.real_radius_m == 0.08 for s in renamed)
