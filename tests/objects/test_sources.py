"""Object sources: embedded pybullet_data selection, user folders, ids, folder errors."""

from __future__ import annotations

import pytest

from dexlite_pipeline.objects.sources import (
    ObjectSourceError,
    builtin_sources,
    collect_sources,
    folder_sources,
    named_pybullet_sources,
    pybullet_data_dir,
    urdf_visual_mesh,
)


def test_missing_folder_is_an_immediate_error_naming_it(tmp_path):
    missing = tmp_path / "no_such_meshes"
    with pytest.raises(ValueError, match="no_such_meshes"):
        collect_sources(0, [str(missing)], [], seed=0)
    with pytest.raises(ObjectSourceError, match="heldout_mesh_dirs"):
        collect_sources(0, [], [str(missing)], seed=0)


def test_user_folder_meshes_are_picked_up(tmp_path):
    (tmp_path / "cup.obj").write_text("v 0 0 0\n")
    (tmp_path / "Block A.STL").write_bytes(b"solid x\nendsolid x\n")
    (tmp_path / "notes.txt").write_text("not a mesh")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "inner.obj").write_text("v 0 0 0\n")
    sources = folder_sources([str(tmp_path)], heldout=False)
    assert [s.object_id for s in sources] == ["user-Block_A", "user-cup"]
    assert {s.source for s in sources} == {"user"} and not any(s.always_heldout for s in sources)
    held = folder_sources([str(tmp_path)], heldout=True)
    assert all(s.always_heldout and s.source == "user_heldout" for s in held)


def test_same_stem_in_two_folders_gets_distinct_stable_ids(tmp_path):
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "cup.obj").write_text("v 0 0 0\n")
    first = collect_sources(0, [str(tmp_path / "a"), str(tmp_path / "b")], [], seed=0)
    again = collect_sources(0, [str(tmp_path / "b"), str(tmp_path / "a")], [], seed=0)
    ids = [s.object_id for s in first]
    assert len(set(ids)) == 2 and all(i.startswith("user-cup-") for i in ids)
    assert {s.file: s.object_id for s in first} == {s.file: s.object_id for s in again}


def test_builtin_selection_is_seeded_and_mixes_named_and_procedural():
    chosen = builtin_sources(40, seed=0)
    assert len(chosen) == 40 and len({s.object_id for s in chosen}) == 40
    kinds = {s.source for s in chosen}
    assert kinds == {"pybullet_named", "pybullet_random"}
    assert [s.object_id for s in builtin_sources(40, seed=0)] == [s.object_id for s in chosen]
    assert [s.object_id for s in builtin_sources(40, seed=1)] != [s.object_id for s in chosen]
    assert builtin_sources(0, seed=0) == []
    for s in chosen:
        assert s.file.endswith((".obj", ".stl")), s.file


def test_named_objects_ship_and_urdf_placement_is_read():
    named = {s.object_id: s for s in named_pybullet_sources()}
    assert {"pb-duck", "pb-bunny", "pb-torus", "pb-jenga"} <= set(named)
    mesh, scale, rpy = urdf_visual_mesh(pybullet_data_dir() / "jenga" / "jenga.urdf")
    assert mesh.name == "jenga.obj" and scale == (0.15, 0.05, 0.03) and rpy == (0.0, 0.0, 0.0)
    assert named["pb-jenga"].scale_xyz == (0.15, 0.05, 0.03)


def test_a_file_listed_twice_is_one_object_and_held_out_wins(tmp_path):
    (tmp_path / "cup.obj").write_text("v 0 0 0\n")
    sources = collect_sources(0, [str(tmp_path), str(tmp_path)], [str(tmp_path)], seed=0)
    assert [(s.object_id, s.always_heldout) for s in sources] == [("user-cup", True)]


def test_dataset_objects_are_rebuilt_from_their_ids_and_split_objects_never_trained_on(tmp_path, caplog):
    from dexlite_pipeline.objects.sources import household_benchmark_list, shapes_benchmark_list

    split_id, shapes_id = household_benchmark_list()[0], shapes_benchmark_list()[0]
    wanted = ("household-mug-000", "household-plate-001-p1", "household-mug-003", split_id, shapes_id,
              split_id + "-p1", "user-my_cup", "household-mug-000")
    with caplog.at_level("WARNING"):
        sources = collect_sources(0, [], [], seed=0, household_count=2, household_first=3, household_families=("mug",),
                                  household_dir=tmp_path / "meshes", rebuilt_training_ids=wanted)
    ids = [s.object_id for s in sources]
    # the drawn household objects (mug 003, 004), then the dataset's not drawn yet, each once, in the dataset's order
    assert ids == ["household-mug-003", "household-mug-004", "household-mug-000", "household-plate-001-p1"]
    assert all(not s.always_heldout and s.source == "household" for s in sources)
    assert all((tmp_path / "meshes" / f"{i}.obj").is_file() for i in ids)
    # what was left out is named with its reason, not silently dropped
    for left_out in (split_id, shapes_id, split_id + "-p1", "user-my_cup"):
        assert any(left_out in r.getMessage() for r in caplog.records)
    assert "held-out split" in caplog.text and "neither a pybullet_data object" in caplog.text


def test_dataset_objects_need_a_dataset(tmp_path):
    from dexlite_pipeline.stages.prepare_objects import dataset_training_ids

    with pytest.raises(ValueError, match="dataset.root is empty"):
        dataset_training_ids("")
    with pytest.raises(ValueError, match="not a grasp dataset"):
        dataset_training_ids(str(tmp_path))


def test_the_repository_dataset_lists_its_training_objects_in_order():
    import pandas as pd

    from dexlite_pipeline.objects.sources import held_out_household_ids
    from dexlite_pipeline.stages.prepare_objects import dataset_training_ids

    table = pd.read_csv("dataset/objects.csv", dtype=str)
    ids = dataset_training_ids("dataset")
    assert list(ids) == list(table.loc[table["split"] == "train", "object_id"])
    assert len(ids) >= 600 and not set(ids) & held_out_household_ids()


def test_procedural_batches_take_consecutive_objects_and_never_the_benchmark_split():
    from dexlite_pipeline.objects.sources import benchmark_object_ids, procedural_sources, random_pybullet_paths

    first = procedural_sources(30)
    second = procedural_sources(30, first=30)
    ids = [s.object_id for s in first + second]
    assert len(set(ids)) == 60 and ids == sorted(ids)  # number order, the two batches disjoint
    assert not set(ids) & benchmark_object_ids()
    assert {s.source for s in first} == {"pybullet_random"}
    available = len(random_pybullet_paths()) - len(benchmark_object_ids())
    assert len(procedural_sources(5, first=available - 2)) == 2  # the last two: a batch past the end is cut short
    with pytest.raises(ObjectSourceError, match="objects.procedural_first"):
        procedural_sources(1, first=available)
    chosen = collect_sources(0, (), (), 0, True, 2, procedural_count=4, procedural_first=30)
    assert [s.object_id for s in chosen][:4] == ids[30:34]
    assert sum(s.always_heldout for s in chosen) == 2  # the benchmark objects asked for, held out
