"""The grasp dataset kept in git (dexlite_pipeline.dataset): additions, loading, labels, merge, card and export.

Synthetic batches only (random poses, made-up outcomes): no simulation, a few seconds in all.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dexlite_pipeline.dataset import (
    BatchRecord,
    DatasetError,
    add_batch,
    dataset_summary,
    export_dexgraspnet,
    load_dataset,
    merge_datasets,
    present_objects,
    write_card,
)
from dexlite_pipeline.dataset.layout import BATCHES_TABLE, OBJECTS_TABLE, REQUIRED_ARRAYS, config_digest
from dexlite_pipeline.io.grasp_store import GraspSet

ENERGIES = ("E_fc", "E_dis", "E_pen", "E_spen", "E_joints", "E_table")
MACHINE = "Linux-test; 2 CPUs"


def palm_pose(position_m, euler_rad=(0.0, 0.0, 0.0)) -> np.ndarray:
    """A (28,) hand pose with the palm at ``position_m`` turned by ``euler_rad`` and every joint at 0."""
    pose = np.zeros(28, np.float32)
    pose[:3], pose[3:6] = position_m, euler_rad
    return pose


def make_grasps(object_ids, per_object: int = 6, seed: int = 0, scale: float = 0.1, source: str = "optimization",
                tabletop: bool = True) -> GraspSet:  # fmt: skip
    """Random grasps of the objects, about half held, energies with a few NaN, the support plane when ``tabletop``."""
    rng = np.random.default_rng(seed)
    n = per_object * len(object_ids)
    held = rng.random(n) < 0.5
    held[::per_object] = True  # every object has a held grasp
    arrays = {
        "object_id": np.repeat(np.asarray(object_ids, dtype=object), per_object),
        "scale": np.full(n, scale, np.float32),
        "hand_pose": rng.normal(0, 0.3, (n, 28)).astype(np.float32),
        **{name: rng.random(n).astype(np.float32) for name in ENERGIES},
        "initial_penetration_mm": rng.random(n).astype(np.float32),
        "lift_success": held,
        "six_dir_success": held & (rng.random(n) < 0.5),
        "failure_reason": np.asarray(["" if h else "dropped" for h in held], dtype=object),
        "source": np.full(n, source, dtype=object),
    }
    arrays["E_table"][1::3] = np.nan
    if tabletop:
        arrays["support_normal"] = np.tile(np.float32([0, 0, 1]), (n, 1))
        arrays["support_offset_m"] = np.full(n, 0.05, np.float32)
    return GraspSet(arrays, {})


def objects_frame(object_ids, split: str = "train", source: str = "household") -> pd.DataFrame:
    return pd.DataFrame({"object_id": list(object_ids), "source": source, "split": split, "real_radius_m": 0.06,
                         "support_nx": 0.0, "support_ny": 0.0, "support_nz": 1.0, "support_offset": 0.5})  # fmt: skip


def record(kind: str = "optimization", day: int = 1) -> BatchRecord:
    return BatchRecord(kind=kind, code_version="0123456789abcdef0123", config={"seed": day, "optimize": {"steps": 300}},
                       cpu_seconds={"optimize": 3600.0 * day, "lift_test": 600.0}, started_utc=f"2026-05-0{day}T08:00:00Z",
                       finished_utc=f"2026-05-0{day}T09:45:00Z", protocol="optimization from scratch, lift test on the table",
                       machine=MACHINE)  # fmt: skip


MUGS = ["household-mug-000", "household-mug-001"]
BOWLS = ["household-bowl-000", "household-bowl-001", "household-bowl-002"]


def folder_bytes(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_round_trip_keeps_values_dtypes_and_stores_strings_without_pickle(tmp_path):
    grasps = make_grasps(MUGS)
    assert add_batch(tmp_path, grasps, objects_frame(MUGS), record()) == 1
    loaded, objects = load_dataset(tmp_path)
    for name, spec in REQUIRED_ARRAYS.items():
        if spec.kind == "str":
            assert loaded.arrays[name].dtype == object and loaded.arrays[name].tolist() == grasps.arrays[name].tolist()
        else:
            assert loaded.arrays[name].dtype == np.dtype(spec.kind), name
            np.testing.assert_array_equal(loaded.arrays[name], grasps.arrays[name])
    np.testing.assert_array_equal(loaded.arrays["support_normal"], grasps.arrays["support_normal"])
    assert loaded.arrays["distinct_label"].dtype == np.int32 and loaded.arrays["batch"].tolist() == [1] * len(grasps)
    assert ((loaded.arrays["distinct_label"] >= 0) == grasps.arrays["lift_success"]).all()
    with np.load(tmp_path / "grasps" / "batch_0001.npz", allow_pickle=False) as archive:
        assert archive["object_id"].dtype.kind == "U" and archive["failure_reason"].dtype.kind == "U"
    assert objects["object_id"].tolist() == MUGS and objects["batch"].tolist() == ["0001", "0001"]
    assert objects["rebuild"].tolist() == [f"household:{o}" for o in MUGS] and objects["scales"].tolist() == ["0.1", "0.1"]
    batch = pd.read_csv(tmp_path / BATCHES_TABLE, dtype=str).iloc[0]
    assert batch["batch"] == "0001" and batch["config_digest"] == config_digest(record().config)
    assert int(batch["held"]) == int(grasps.arrays["lift_success"].sum())
    held, _ = load_dataset(tmp_path, object_ids=["household-mug-001"], held_only=True)
    assert set(held.object_id) == {"household-mug-001"} and held.arrays["lift_success"].all()


def test_same_batches_give_byte_identical_files(tmp_path):
    for folder in (tmp_path / "a", tmp_path / "b"):
        add_batch(folder, make_grasps(MUGS, seed=1), objects_frame(MUGS), record())
        add_batch(folder, make_grasps(MUGS, seed=2, source="loop_round_1"), objects_frame([]), record("loop_round_1", day=2))
        write_card(folder, "Protocol text.")
    first, second = folder_bytes(tmp_path / "a"), folder_bytes(tmp_path / "b")
    assert sorted(first) == ["CARD.md", BATCHES_TABLE, "configs/batch_0001.json", "configs/batch_0002.json",
                             "grasps/batch_0001.npz", "grasps/batch_0002.npz", OBJECTS_TABLE]  # fmt: skip
    assert first == second
    with zipfile.ZipFile(tmp_path / "a" / "grasps" / "batch_0001.npz") as archive:
        assert {info.date_time for info in archive.infolist()} == {(1980, 1, 1, 0, 0, 0)}


def test_optimization_batch_readding_a_present_object_is_refused_and_writes_nothing(tmp_path):
    add_batch(tmp_path, make_grasps(MUGS), objects_frame(MUGS), record())
    before = folder_bytes(tmp_path)
    again = ["household-bowl-000", "household-mug-001"]
    with pytest.raises(DatasetError, match=r"object household-mug-001 is already in the dataset \(batch 0001\)") as error:
        add_batch(tmp_path, make_grasps(again), objects_frame(again), record(day=2))
    assert "\n" not in str(error.value)
    assert folder_bytes(tmp_path) == before
    # a loop round may add grasps to a present object
    assert add_batch(tmp_path, make_grasps(["household-mug-001"], source="loop_round_1"), None, record("loop_round_1")) == 2


@pytest.mark.parametrize(("change", "message"), [
    (lambda a: a.pop("E_table"), "grasps: missing required array: E_table"),
    (lambda a: a.update(lift_success=a["lift_success"][:-1]), "grasps: array 'lift_success' has shape (11,), expected (12,)"),
    (lambda a: a.update(six_dir_success=a["six_dir_success"].astype(np.float32)), "array 'six_dir_success' has dtype float32, expected bool"),
    (lambda a: a.update(contact_index=np.zeros((12, 4))), "arrays not in the dataset schema: contact_index"),
    (lambda a: a.pop("support_offset_m"), "support_normal given without support_offset_m"),
])  # fmt: skip
def test_bad_arrays_give_one_line_errors_naming_them(tmp_path, change, message):
    grasps = make_grasps(MUGS)
    change(grasps.arrays)
    with pytest.raises(DatasetError) as error:
        add_batch(tmp_path, grasps, objects_frame(MUGS), record())
    assert message in str(error.value) and "\n" not in str(error.value)
    assert not tmp_path.joinpath(BATCHES_TABLE).exists()


def test_objects_frame_and_record_are_checked(tmp_path):
    with pytest.raises(DatasetError, match="object household-mug-001 has grasps but no row in the objects frame"):
        add_batch(tmp_path, make_grasps(MUGS), objects_frame(MUGS[:1]), record())
    with pytest.raises(DatasetError, match="objects: column 'split' has 'test'"):
        add_batch(tmp_path, make_grasps(MUGS), objects_frame(MUGS, split="test"), record())
    with pytest.raises(DatasetError, match="record: kind 'loop' is not"):
        add_batch(tmp_path, make_grasps(MUGS), objects_frame(MUGS), record("loop"))
    add_batch(tmp_path, make_grasps(MUGS), objects_frame(MUGS), record())
    with pytest.raises(DatasetError, match="object household-mug-000: split differ from the dataset's row"):
        add_batch(tmp_path, make_grasps(MUGS[:1]), objects_frame(MUGS[:1], split="heldout"), record("model"))


def test_a_model_batch_adds_to_present_objects_whose_rest_pose_agrees_within_a_micrometre(tmp_path):
    add_batch(tmp_path, make_grasps(MUGS), objects_frame(MUGS), record())
    moved = objects_frame(MUGS[:1])
    moved["support_offset"] = 0.5 + 1e-4  # a rest height a tenth of a millimetre off: another pose of the object
    with pytest.raises(DatasetError, match="object household-mug-000: support_offset differ from the dataset's row"):
        add_batch(tmp_path, make_grasps(MUGS[:1]), moved, record("model"))
    same = objects_frame(MUGS[:1])
    same["support_offset"] = 0.5 + 3e-7  # the table test of the same asset in another run (measured: 0.3 um, 1 urad)
    same["support_nx"] = 8e-7
    assert add_batch(tmp_path, make_grasps(MUGS[:1]), same, record("model")) == 2
    assert load_dataset(tmp_path)[1].set_index("object_id").loc[MUGS[0], "support_offset"] == 0.5  # the stored row stays


def test_distinct_labels_stay_consistent_across_batches(tmp_path):
    mug = MUGS[0]

    def batch(poses, held, scale=0.1, source="optimization"):
        n = len(poses)
        grasps = make_grasps([mug], per_object=n, source=source, tabletop=False)
        grasps.arrays.update(hand_pose=np.stack(poses), lift_success=np.asarray(held), scale=np.full(n, scale, np.float32))
        return grasps

    first = batch([palm_pose((0.1, 0, 0)), palm_pose((-0.1, 0, 0)), palm_pose((0.105, 0, 0)), palm_pose((0, 0.1, 0))],
                  [True, True, True, False])  # fmt: skip
    add_batch(tmp_path, first, objects_frame([mug]), record())
    labels = load_dataset(tmp_path)[0].arrays["distinct_label"].tolist()
    assert labels == [0, 1, 0, -1]
    near_second = palm_pose((-0.09, 0.005, 0), (0.2, 0, 0))  # 1.1 cm and 11.5 deg from the second grasp
    turned_first = palm_pose((0.1, 0, 0), (0, 0, np.pi / 2))  # same place as the first, turned 90 deg
    later = batch([near_second, turned_first, palm_pose((0.1, 0, 0)), palm_pose((0.3, 0, 0)), palm_pose((0.1, 0, 0))],
                  [True, True, False, True, True], source="loop_round_1")  # fmt: skip
    add_batch(tmp_path, later, objects_frame([]), record("loop_round_1", day=2))
    other_scale = batch([palm_pose((0.1, 0, 0))], [True], scale=0.12, source="model")
    add_batch(tmp_path, other_scale, objects_frame([]), record("model", day=3))
    loaded, objects = load_dataset(tmp_path)
    assert loaded.arrays["distinct_label"].tolist() == [0, 1, 0, -1, 1, 2, -1, 3, 0, 4]
    assert pd.read_csv(tmp_path / BATCHES_TABLE)["distinct_held_added"].tolist() == [2, 2, 1]
    assert objects["scales"].tolist() == ["0.1;0.12"]
    assert dataset_summary(tmp_path)["per_object"][mug]["distinct_held"] == 5


def test_present_objects_and_a_half_finished_addition(tmp_path):
    assert present_objects(tmp_path / "missing") == set()
    add_batch(tmp_path, make_grasps(MUGS), objects_frame(MUGS), record())
    assert present_objects(tmp_path) == set(MUGS)
    # an addition killed after writing objects.csv but before batches.csv: its rows are not part of the dataset
    table = pd.read_csv(tmp_path / OBJECTS_TABLE, dtype=str, keep_default_na=False)
    leftover = table.iloc[[0]].assign(object_id="household-can-000", batch="0002")
    pd.concat([table, leftover]).to_csv(tmp_path / OBJECTS_TABLE, index=False, lineterminator="\n")
    assert present_objects(tmp_path) == set(MUGS)
    assert add_batch(tmp_path, make_grasps(["household-can-000"]), objects_frame(["household-can-000"]), record(day=2)) == 2
    assert present_objects(tmp_path) == {*MUGS, "household-can-000"}


def test_merge_renumbers_batches_and_refuses_clashing_objects(tmp_path):
    one, two, dest = tmp_path / "one", tmp_path / "two", tmp_path / "dest"
    add_batch(one, make_grasps(MUGS, seed=1), objects_frame(MUGS), record())
    add_batch(one, make_grasps(MUGS[:1], seed=2, source="loop_round_1"), objects_frame([]), record("loop_round_1", day=2))
    add_batch(two, make_grasps(BOWLS, seed=3), objects_frame(BOWLS), record(day=3))
    assert merge_datasets([one, two], dest) == {str(one): {1: 1, 2: 2}, str(two): {1: 3}}
    merged, objects = load_dataset(dest)
    for source in (one, two):
        original = load_dataset(source)[0]
        mine = np.isin(merged.object_id, list(set(original.object_id)))
        np.testing.assert_array_equal(merged.hand_pose[mine], original.hand_pose)
        np.testing.assert_array_equal(merged.arrays["distinct_label"][mine], original.arrays["distinct_label"])
    assert objects.set_index("object_id")["batch"].to_dict() == {**dict.fromkeys(MUGS, "0001"), **dict.fromkeys(BOWLS, "0003")}
    assert pd.read_csv(dest / BATCHES_TABLE, dtype=str)["batch"].tolist() == ["0001", "0002", "0003"]

    clash = tmp_path / "clash"
    add_batch(clash, make_grasps(BOWLS[:1]), objects_frame(BOWLS[:1], split="heldout"), record())
    before = folder_bytes(dest)
    with pytest.raises(DatasetError, match="object household-bowl-000: split differ between"):
        merge_datasets([clash], dest)
    assert folder_bytes(dest) == before
    # the same object, described identically, may come from two datasets: its held grasps get dest's labels
    same = tmp_path / "same"
    add_batch(same, load_dataset(two, object_ids=BOWLS[:1])[0], objects_frame(BOWLS[:1]), record(day=4))
    merge_datasets([same], dest)
    again = load_dataset(dest, object_ids=BOWLS[:1])[0]
    first, repeat = again.arrays["batch"] == 3, again.arrays["batch"] == 4
    np.testing.assert_array_equal(again.arrays["distinct_label"][first], again.arrays["distinct_label"][repeat])
    assert pd.read_csv(dest / BATCHES_TABLE)["distinct_held_added"].tolist()[-1] == 0


def test_card_shows_counts_and_progress_toward_the_target(tmp_path):
    spread_out = [palm_pose((0.05 * (i % 6), 0.05 * (i // 6), 0)) for i in range(32)]  # 32 distinct held grasps
    grasps = make_grasps(MUGS[:1], per_object=32, tabletop=False)
    grasps.arrays.update(hand_pose=np.stack(spread_out), lift_success=np.ones(32, bool))
    add_batch(tmp_path, grasps, objects_frame(MUGS[:1]), record())
    add_batch(tmp_path, make_grasps(BOWLS, tabletop=False), objects_frame(BOWLS), record(day=2))
    add_batch(tmp_path, make_grasps(["pb-random-001"], tabletop=False), objects_frame(["pb-random-001"], "heldout", "pybullet_data"), record(day=3))
    summary = dataset_summary(tmp_path)
    assert summary["objects"] == 5 and summary["objects_by_split"] == {"train": 4, "heldout": 1}
    assert summary["target"]["household_training_objects"] == 4
    assert summary["target"]["household_training_objects_at_target"] == 1
    assert summary["per_family"]["mug"]["distinct_held"] == 32 and summary["per_family"]["bowl"]["objects"] == 3
    assert summary["distinct_held_per_object"]["max"] == 32
    text = write_card(tmp_path, "Each batch: 2 hours on 2 cores.").read_text()
    assert "**1 of 200 household training objects reach 30 distinct held grasps (0.5%)**" in text
    assert "| objects | 5 (4 training, 1 held out) |" in text and f"| grasps tried | {summary['grasps']} |" in text
    assert "Each batch: 2 hours on 2 cores." in text and "load_dataset(" in text and MACHINE in text
    assert "| mug | 1 | 32 | 32 | 32 |" in text
    assert "pybullet_data:random_urdfs/001/001.urdf" in pd.read_csv(tmp_path / OBJECTS_TABLE)["rebuild"].tolist()


def test_export_writes_dexgraspnets_layout_of_the_held_grasps(tmp_path):
    import trimesh

    from dexlite_pipeline.io.safe_pickle import load_npy_restricted
    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    box = trimesh.creation.box(extents=(1.2, 0.8, 0.6))
    write_asset(box, MUGS[0], tmp_path / "objects", AssetBuildSettings(sdf_resolution=16, surface_points=200), {"source": "test"}, [box])
    grasps = make_grasps(MUGS)
    add_batch(tmp_path / "dataset", grasps, objects_frame(MUGS), record())
    counts = export_dexgraspnet(tmp_path / "dataset", tmp_path / "out", [tmp_path / "objects"])
    held = grasps.arrays["lift_success"]
    assert counts == {"objects": 2, "grasps": int(held.sum()), "missing_assets": [MUGS[1]]}
    entries = load_npy_restricted(tmp_path / "out" / "dataset" / f"{MUGS[0]}.npy")
    mine = held & (grasps.object_id == MUGS[0])
    assert len(entries) == int(mine.sum()) and set(entries[0]) == {"qpos", "scale", "grasp_type"}
    assert {entry["grasp_type"] for entry in entries} == {"power"}  # a batch without types: power grasps
    assert entries[0]["qpos"]["WRJTx"] == pytest.approx(float(grasps.hand_pose[mine][0, 0]))
    assert (tmp_path / "out" / "meshdata" / MUGS[0] / "coacd" / "decomposed.obj").is_file()


def typed(grasps: GraspSet, types: list[str]) -> GraspSet:
    """``grasps`` with ``grasp_type`` cycling through ``types``."""
    grasps.arrays["grasp_type"] = np.resize(np.asarray(types, dtype=object), len(grasps))
    return grasps


def test_grasp_types_are_stored_loaded_and_older_batches_load_as_power(tmp_path):
    add_batch(tmp_path, make_grasps(MUGS), objects_frame(MUGS), record())  # made before grasp types: no grasp_type
    add_batch(tmp_path, typed(make_grasps(BOWLS, seed=1), ["pinch", "power", "tripod"]), objects_frame(BOWLS), record(day=2))
    with np.load(tmp_path / "grasps" / "batch_0001.npz", allow_pickle=False) as archive:
        assert "grasp_type" not in archive.files
    loaded, _ = load_dataset(tmp_path)
    first = loaded.arrays["batch"] == 1
    assert loaded.arrays["grasp_type"].dtype == object and set(loaded.arrays["grasp_type"][first]) == {"power"}
    assert loaded.arrays["grasp_type"][~first].tolist() == np.resize(["pinch", "power", "tripod"], int((~first).sum())).tolist()
    only_old, _ = load_dataset(tmp_path, object_ids=MUGS)
    assert set(only_old.arrays["grasp_type"]) == {"power"}
    with pytest.raises(DatasetError, match="array 'grasp_type' has 1 empty values"):
        bad = typed(make_grasps(["household-cup-000"]), ["pinch"])
        bad.arrays["grasp_type"][2] = ""
        add_batch(tmp_path, bad, objects_frame(["household-cup-000"]), record(day=3))


def test_card_counts_held_and_distinct_held_grasps_per_type(tmp_path):
    grasps = typed(make_grasps(MUGS[:1], per_object=8, tabletop=False), ["pinch", "lateral"])
    same_palm = [palm_pose((0.0, 0.0, 0.0))] * 4 + [palm_pose((0.05 * i, 0.1, 0.0)) for i in range(4)]
    held = np.array([True, True, True, False, True, True, False, False])
    grasps.arrays.update(hand_pose=np.stack(same_palm), lift_success=held)
    add_batch(tmp_path, grasps, objects_frame(MUGS[:1]), record())
    old = make_grasps(BOWLS[:1], per_object=4, tabletop=False)
    old.arrays["lift_success"] = np.array([True, False, False, False])
    add_batch(tmp_path, old, objects_frame(BOWLS[:1]), record(day=2))
    per_type = dataset_summary(tmp_path)["per_type"]
    # pinch: rows 0, 2 (same palm: one distinct grasp), 4 held; lateral: rows 1 (same palm as 0), 5 held; 7 not held
    assert per_type["pinch"] == {"grasps": 4, "held": 3, "distinct_held": 2, "objects_with_held": 1}
    assert per_type["lateral"] == {"grasps": 4, "held": 2, "distinct_held": 2, "objects_with_held": 1}
    assert per_type["power"] == {"grasps": 4, "held": 1, "distinct_held": 1, "objects_with_held": 1}
    text = write_card(tmp_path, "").read_text()
    assert "## Grasp types" in text and "| pinch | 4 | 3 | 75.0% | 2 | 1 |" in text and "| power | 4 | 1 | 25.0% | 1 | 1 |" in text
    assert "made before grasp types existed, with the power template only" in text


def test_export_writes_each_grasps_type(tmp_path):
    grasps = typed(make_grasps(MUGS), ["tripod", "pinch"])
    add_batch(tmp_path / "dataset", grasps, objects_frame(MUGS), record())
    export_dexgraspnet(tmp_path / "dataset", tmp_path / "out")
    from dexlite_pipeline.io.safe_pickle import load_npy_restricted

    for object_id in MUGS:
        mine = grasps.arrays["lift_success"] & (grasps.object_id == object_id)
        entries = load_npy_restricted(tmp_path / "out" / "dataset" / f"{object_id}.npy")
        assert [entry["grasp_type"] for entry in entries] == grasps.arrays["grasp_type"][mine].tolist()
