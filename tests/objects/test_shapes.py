"""Shape families and perturbations: closed solids at real size that rest on the table, ids that rebuild them, the
original twelve unchanged, perturbations within their documented sizes, and the shapes split never trained on."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
import yaml
from scipy.spatial import Delaunay

from dexlite_pipeline.config import ConfigError, validate_config
from dexlite_pipeline.objects import household as hh
from dexlite_pipeline.objects import perturb
from dexlite_pipeline.objects.sources import (
    SHAPES_SPLIT_FILE,
    ObjectSourceError,
    benchmark_object_ids,
    collect_sources,
    held_out_household_ids,
    household_benchmark_list,
    rebuilt_source_of,
    shapes_benchmark_list,
)

# family -> ((smallest, largest) of the smallest extent, (smallest, largest) of the largest extent), metres: the real
# objects each family's parameter docstring names (a pan's largest extent includes its handle).
EXTENT_RANGES = {
    "plate": ((0.018, 0.031), (0.18, 0.28)),
    "pot": ((0.09, 0.16), (0.19, 0.31)),
    "pan": ((0.06, 0.11), (0.33, 0.50)),
    "kettle": ((0.14, 0.18), (0.21, 0.27)),
    "jug": ((0.09, 0.12), (0.15, 0.225)),
    "handled_bottle": ((0.08, 0.12), (0.19, 0.29)),
    "bevelled_box": ((0.03, 0.12), (0.06, 0.20)),
    "screwdriver": ((0.02, 0.032), (0.14, 0.27)),
    "knife": ((0.014, 0.02), (0.21, 0.32)),
    "spoon": ((0.008, 0.014), (0.14, 0.21)),
    "scissors": ((0.006, 0.0095), (0.13, 0.21)),
    "pliers": ((0.01, 0.014), (0.14, 0.19)),
    "apple": ((0.065, 0.095), (0.07, 0.10)),
    "pear": ((0.06, 0.08), (0.10, 0.145)),
    "banana": ((0.03, 0.04), (0.16, 0.23)),
    "potato": ((0.025, 0.08), (0.06, 0.125)),
    "toy_figure": ((0.025, 0.07), (0.08, 0.15)),
}

# The original twelve as generated before the shape families were added: (vertices, volume m^3, sha-256 of the .obj
# text, first 16 hex digits). The dataset rebuilds its objects from their ids, so these must never change.
ORIGINAL_MESHES = {
    "household-mug-000": (1727, 1.439162813e-04, "4a3e579e56c9dc7c"),
    "household-mug-900": (1805, 1.149918065e-04, "645154309ec810c2"),
    "household-bowl-000": (3778, 1.369812638e-04, "357787462e180e59"),
    "household-bowl-900": (3522, 9.157129024e-05, "66d3653ccd6f2005"),
    "household-bottle-000": (2754, 4.732186075e-04, "fd0d7b45f245e3ad"),
    "household-bottle-900": (2754, 6.851200019e-04, "1888d9bdb8172954"),
    "household-cereal_box-000": (8, 3.996432095e-03, "ffaa0121ece9eb5c"),
    "household-cereal_box-900": (8, 4.280740496e-03, "cee01e7981cd77cb"),
    "household-cup-000": (898, 6.752405644e-05, "632abac7b19613e4"),
    "household-cup-900": (1090, 1.382034379e-04, "06e8efb1aa626dba"),
    "household-can-000": (322, 3.904867160e-04, "655b7b9b90afa1ce"),
    "household-can-900": (322, 3.675884248e-04, "3cbdfcec11c38d1d"),
    "household-wine_bottle-000": (2754, 8.416097000e-04, "a0dd98ef7041495e"),
    "household-wine_bottle-900": (2754, 9.505899195e-04, "f483495aa3cfce62"),
    "household-milk_carton-000": (18, 1.119618689e-03, "d78f99b7aa48bb00"),
    "household-milk_carton-900": (18, 1.626819860e-03, "c73f5bde733db6dc"),
    "household-jar-000": (1090, 5.008087259e-04, "ce797fff5bd06140"),
    "household-jar-900": (1090, 4.918119909e-04, "e674611d937a7505"),
    "household-box-000": (8, 8.792084922e-04, "2880ab53a523a4fa"),
    "household-box-900": (8, 1.021880589e-03, "7995efe53a405d69"),
    "household-hammer-000": (81, 2.603513753e-04, "e2a9828d8173fdd2"),
    "household-hammer-900": (73, 2.517124287e-04, "c88a30ff44a34183"),
    "household-spatula-000": (78, 1.261338355e-04, "606af95f42000af3"),
    "household-spatula-900": (78, 8.707903100e-05, "4a7cdbf23f0e76f4"),
}

# Largest displacement (m) the module docstring of objects/perturb.py gives each step kind (scale: a fraction).
DOCUMENTED_MAX_M = {"lean": 0.010, "bow": 0.012, "dent": 0.006, "bump": 0.004, "noise": 0.0006}


def _closed_single_solid_on_table(mesh) -> None:
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.body_count == 1 and mesh.volume > 0
    assert mesh.bounds[0][2] == pytest.approx(0.0, abs=1e-12)


def _rests_on_its_base(mesh) -> bool:
    """Whether the centre of mass is above the convex hull of the points within 0.2 mm of the table (statically stable)."""
    contact = mesh.vertices[mesh.vertices[:, 2] < 2e-4][:, :2]
    return bool(Delaunay(contact).find_simplex(mesh.center_mass[:2]) >= 0)


def test_the_original_twelve_are_unchanged_and_drawn_by_default():
    assert list(hh.FAMILIES) == ["mug", "bowl", "bottle", "cereal_box", "cup", "can", "wine_bottle", "milk_carton", "jar", "box",
                                 "hammer", "spatula"]
    for object_id, (vertices, volume, digest) in ORIGINAL_MESHES.items():
        mesh = hh.household_object(object_id).mesh
        assert len(mesh.vertices) == vertices and mesh.volume == pytest.approx(volume, rel=1e-8), object_id
        assert hashlib.sha256(mesh.export(file_type="obj").encode()).hexdigest()[:16] == digest, object_id
    assert hh.training_household_ids(13) == [hh.household_id(f, 0) for f in hh.FAMILIES] + ["household-mug-001"]


def test_every_shape_family_has_its_size_range_and_there_are_at_least_twenty_families():
    assert set(EXTENT_RANGES) == set(hh.SHAPE_FAMILIES) and not set(hh.SHAPE_FAMILIES) & set(hh.FAMILIES)
    assert len(hh.ALL_FAMILIES) >= 20 and len(hh.SHAPE_FAMILIES) >= 10


@pytest.mark.parametrize("family", sorted(EXTENT_RANGES))
def test_shape_family_instances_are_closed_solids_at_real_size_resting_on_the_table(family):
    sizes = []
    for index in range(4):
        obj = hh.household_object(hh.household_id(family, index))
        _closed_single_solid_on_table(obj.mesh)
        (low_min, low_max), (high_min, high_max) = EXTENT_RANGES[family]
        extents = np.sort(obj.mesh.extents)
        assert low_min <= extents[0] <= low_max and high_min <= extents[2] <= high_max, (obj.object_id, extents)
        assert _rests_on_its_base(obj.mesh), obj.object_id
        sizes.append(obj.mesh.volume)
    assert np.ptp(sizes) > 0, "instances of a family must differ"


@pytest.mark.parametrize("family", ["mug", "plate", "hammer", "scissors", "apple", "bevelled_box"])
@pytest.mark.parametrize("index, variant", [(3, 1), (5, 2)])
def test_perturbed_instances_stay_closed_on_the_table_within_their_documented_sizes(family, index, variant):
    obj = hh.household_object(hh.household_id(family, index, variant))
    plan = obj.params["perturbation"]
    _closed_single_solid_on_table(obj.mesh)
    assert _rests_on_its_base(obj.mesh), obj.object_id
    kinds = [step["kind"] for step in plan]
    assert kinds[0] == "scale" and {"dent", "bump"} & set(kinds)
    plain = hh.household_object(hh.household_id(family, index)).mesh
    base = perturb.refined(plain, perturb.refine_edge(plain))
    vertices = np.asarray(base.vertices)
    for step in plan:
        assert step["lipschitz"] < 1.0, step  # a one-to-one map of space: the solid cannot fold through itself
        moved = perturb.apply_step(vertices, step)
        assert np.linalg.norm(moved - vertices, axis=1).max() <= step["max_displacement"] * (1 + 1e-9) + 1e-12, step["kind"]
        if step["kind"] == "scale":
            assert all(perturb.SCALE_RANGE[0] <= f <= perturb.SCALE_RANGE[1] for f in step["factors"])
        else:
            assert step["max_displacement"] <= DOCUMENTED_MAX_M[step["kind"]], step
        vertices = moved
    assert np.allclose(vertices, obj.mesh.vertices, atol=1e-12)  # the mesh is the plan applied, vertex for vertex
    assert hh.household_object(obj.object_id).mesh.export(file_type="obj") == obj.mesh.export(file_type="obj")


def test_perturbation_changes_the_shape_and_variants_differ():
    plain = hh.household_object("household-can-004").mesh
    first, second = (hh.household_object(f"household-can-004-p{k}").mesh for k in (1, 2))
    assert not np.allclose(first.extents, second.extents)
    assert abs(first.volume / plain.volume - 1) > 1e-3
    # within ±12% per axis, plus at most a bend, dents and bumps of a few millimetres
    assert np.all(first.extents <= plain.extents * 1.12 + 0.03) and np.all(first.extents >= plain.extents * 0.88 - 0.03)


@pytest.mark.parametrize("family", sorted(hh.ALL_FAMILIES))
def test_ids_round_trip(family):
    for index, variant in [(0, 0), (7, 0), (912, 0), (40, 1), (3, 12)]:
        object_id = hh.household_id(family, index, variant)
        assert hh.parse_household_id(object_id) == (family, index, variant)
        assert hh.base_household_id(object_id) == hh.household_id(family, index)
    assert hh.household_id(family, 40, 1) == f"household-{family}-040-p1"


@pytest.mark.parametrize("bad", ["household-mug-001-p0", "household-mug-001-px", "household-mug-001-p", "household-mug-p1",
                                 "household-teapot-001-p1", "household-plate"])
def test_bad_perturbed_ids_are_named_in_the_error(bad):
    with pytest.raises(ValueError, match=bad):
        hh.parse_household_id(bad)


def _rule_ids() -> list[str]:
    """The shapes split as its rule says (shapes_split.yaml, "rule")."""
    ids = []
    for k in range(3):
        ids += [hh.household_id(f, 900 + k) for f in hh.SHAPE_FAMILIES]
        ids += [hh.household_id(f, 900 + k, 1) for f in hh.ALL_FAMILIES] if k < 2 else []
    return ids


def test_shapes_split_follows_its_rule_was_checked_and_is_never_trained_on():
    ids = shapes_benchmark_list()
    record = yaml.safe_load(SHAPES_SPLIT_FILE.read_text())
    assert ids == _rule_ids() and len(set(ids)) == len(ids)
    assert record["checked"].startswith(f"all {len(ids)} prepared (status ok) and table-stable"), record["checked"]
    assert {hh.parse_household_id(i).family for i in ids} == set(hh.ALL_FAMILIES)
    assert not set(ids) & (set(household_benchmark_list()) | benchmark_object_ids())
    held = held_out_household_ids()
    held_instances = {hh.base_household_id(i) for i in held}
    # Training draws of every family and variants, past the 900s, skip both splits and every variant of their instances.
    training = hh.training_household_ids(len(hh.ALL_FAMILIES) * 3 * 1000, held, tuple(hh.ALL_FAMILIES), (0, 1, 2))
    assert len(training) == len(set(training)) and not set(training) & held
    assert not {hh.base_household_id(i) for i in training} & held_instances
    assert hh.training_household_ids(3, held, ("plate",), (1,)) == ["household-plate-000-p1", "household-plate-001-p1", "household-plate-002-p1"]


def test_collect_sources_draws_perturbed_variants_and_the_shapes_split(tmp_path):
    folder = tmp_path / "household_meshes"
    sources = collect_sources(0, [], [], seed=0, household_count=3, household_families=("spoon", "mug"), household_variants=(0, 1),
                              shapes_benchmark_objects=2, household_dir=folder)
    split = shapes_benchmark_list()
    assert [s.object_id for s in sources] == ["household-spoon-000", "household-spoon-000-p1", "household-mug-000", *split[:2]]
    assert [s.source for s in sources] == ["household"] * 3 + ["household_shapes_benchmark"] * 2
    assert [s.always_heldout for s in sources] == [False, False, False, True, True]
    assert sorted(p.name for p in folder.iterdir()) == sorted(f"{s.object_id}.obj" for s in sources)
    rebuilt = rebuilt_source_of("household-spoon-000-p1", tmp_path / "again")
    assert rebuilt.source == "household" and rebuilt.real_radius_m == pytest.approx(sources[1].real_radius_m)
    assert rebuilt_source_of(split[0], tmp_path / "again").source == "household_shapes_benchmark"


def test_shapes_and_variant_errors_name_the_key(tmp_path):
    with pytest.raises(ObjectSourceError, match="objects.shapes_benchmark_objects: 999 asked"):
        collect_sources(0, [], [], seed=0, shapes_benchmark_objects=999, household_dir=tmp_path)
    for variants in [(), (0, 0), (-1,)]:
        with pytest.raises(ObjectSourceError, match="objects.household_variants"):
            collect_sources(0, [], [], seed=0, household_count=1, household_variants=variants, household_dir=tmp_path)
    section = {"builtin_count": 0, "mesh_dirs": [], "heldout_mesh_dirs": []}
    config = {"seed": 0, "device": "cpu", "shards": 1, "objects": section, "dexgraspnet": {"root": ""}}
    validate_config({**config, "objects": {**section, "household_variants": [0, 1], "shapes_benchmark_objects": 5}})
    for key, value in [("household_variants", [0, 0]), ("household_variants", [-1]), ("shapes_benchmark_objects", -1)]:
        with pytest.raises(ConfigError, match=key):
            validate_config({**config, "objects": {**section, key: value}})


def test_a_perturbed_object_and_one_of_the_shapes_split_pass_preparation_and_the_stability_test(tmp_path):
    """A perturbed training spoon (dense, refined mesh) and the split's first object through the prepare-objects stage
    with small grids and little CoACD effort (acceptance, not quality), then the table test at the default settings."""
    import json

    from dexlite_pipeline.cli import main
    from dexlite_pipeline.objects.assets import read_catalog
    from dexlite_pipeline.objects.config import StabilityConfig
    from dexlite_pipeline.objects.stability import stability_filter

    out = tmp_path / "objects"
    objects = {"builtin_count": 0, "benchmark_objects": 0, "household_count": 1, "household_families": ["spoon"],
               "household_variants": [1], "shapes_benchmark_objects": 1, "sdf_resolution": 32, "surface_points": 256,
               "coacd_max_convex_hull": 4, "coacd_mcts_iterations": 10, "coacd_mcts_nodes": 5, "coacd_mcts_max_depth": 1,
               "coacd_resolution": 300}
    cfg = json.dumps({"seed": 0, "objects": objects})
    assert main(["prepare-objects", "--config-json", cfg, "--catalog", str(out / "catalog.parquet"),
                 "--record", str(out / "prepare_config.json"), "--threads", "1"]) == 0
    catalog = read_catalog(out).set_index("object_id")
    first = shapes_benchmark_list()[0]
    assert sorted(catalog.index) == sorted(["household-spoon-000-p1", first])
    assert (catalog["status"] == "ok").all(), catalog["reason"].to_dict()
    assert catalog.loc[first, "split"] == "heldout" and catalog.loc[first, "source"] == "household_shapes_benchmark"
    table = stability_filter([str(out)], 0, StabilityConfig(), 1)
    assert table["stable"].all(), table.to_dict("records")
