"""One hand per dataset: a batch of a hand from its MJCF (the tests' three-finger hand, poses of 6 + 9 numbers) records the
hand and its joint names in its archive, loads and exports with them; a batch of another hand than the dataset's is
refused with the reason and writes nothing; a run of another hand refuses the dataset; Shadow Hand batches (the
repository's dataset/ among them) have no hand members and load as before."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from test_store import MUGS, BOWLS, folder_bytes, make_grasps, objects_frame, record

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "hand"))

from three_finger import write_three_finger  # noqa: E402

from dexlite_pipeline.dataset import DatasetError, add_batch, export_dexgraspnet, load_dataset, merge_datasets  # noqa: E402
from dexlite_pipeline.dataset.files import read_npz  # noqa: E402
from dexlite_pipeline.dataset.hand import HAND_MEMBERS  # noqa: E402
from dexlite_pipeline.dataset.layout import grasps_path  # noqa: E402
from dexlite_pipeline.dataset.store import load_batch, stored_hand  # noqa: E402
from dexlite_pipeline.io.grasp_store import GraspSet  # noqa: E402

JOINTS = [f"{finger}_j{k}" for finger in ("f1", "f2", "th") for k in range(3)]
REPOSITORY_DATASET = Path(__file__).resolve().parents[2] / "dataset"


@pytest.fixture(scope="module")
def hand(tmp_path_factory) -> dict:
    """The three-finger hand's record (``hand``: its file, ``hand_sha256``, ``joint_names``)."""
    from dexlite_pipeline.hand.choice import hand_record

    return hand_record(str(write_three_finger(tmp_path_factory.mktemp("three_finger_dataset"))))


def three_finger_grasps(hand: dict, object_ids, seed: int = 0) -> GraspSet:
    """``make_grasps`` with poses of 6 + 9 numbers (palm as before, the nine joints random) and the hand's record."""
    grasps = make_grasps(object_ids, seed=seed)
    pose = np.concatenate([grasps.hand_pose[:, :6], np.random.default_rng(seed).uniform(0, 1, (len(grasps), 9)).astype(np.float32)], axis=1)
    return GraspSet({**grasps.arrays, "hand_pose": pose}, dict(hand))


def test_a_batch_of_another_hand_records_it_and_loads_and_exports_with_it(tmp_path, hand):
    dataset = tmp_path / "three_finger"
    add_batch(dataset, three_finger_grasps(hand, MUGS), objects_frame(MUGS), record())
    add_batch(dataset, three_finger_grasps(hand, BOWLS, seed=1), objects_frame(BOWLS), record(day=2))
    stored = read_npz(grasps_path(dataset, 1), HAND_MEMBERS)
    assert stored["hand"].tolist() == [hand["hand"]] and stored["joint_names"].tolist() == JOINTS and stored["hand_sha256"].tolist() == [hand["hand_sha256"]]
    grasps, _ = load_dataset(dataset)
    assert grasps.hand_pose.shape == (6 * 5, 15) and grasps.attrs == {"hand": hand["hand"], "joint_names": JOINTS, "hand_sha256": hand["hand_sha256"]}
    assert (grasps.arrays["distinct_label"][grasps.arrays["lift_success"]] >= 0).all()  # distinct labels over 15-number poses
    assert load_batch(dataset, 2).attrs["joint_names"] == JOINTS and "hand" not in load_batch(dataset, 2).arrays

    out = tmp_path / "export"
    export_dexgraspnet(dataset, out)
    written = json.loads((out / "hand.json").read_text())
    assert written["hand"] == hand["hand"] and written["joint_names"] == JOINTS
    entries = np.load(out / "dataset" / f"{MUGS[0]}.npy", allow_pickle=True)
    assert set(JOINTS) <= set(entries[0]["qpos"])

    from dexlite_pipeline.dataset import write_card

    card = write_card(dataset, "protocol").read_text()
    assert f"Grasps of the hand `{hand['hand']}` (joints {', '.join(JOINTS)})" in card and "# (N, 15) float32" in card

    merged = tmp_path / "merged"
    merge_datasets([dataset], merged)
    assert stored_hand(merged) == grasps.attrs and load_dataset(merged)[0].hand_pose.shape == (30, 15)


def test_a_batch_of_another_hand_than_the_datasets_is_refused_and_writes_nothing(tmp_path, hand):
    shadow = tmp_path / "shadow"
    add_batch(shadow, make_grasps(MUGS), objects_frame(MUGS), record())
    before = folder_bytes(shadow)
    with pytest.raises(DatasetError, match=r"holds grasps of hand shadow, this batch is of hand .*three_finger.xml: a dataset holds one hand"):
        add_batch(shadow, three_finger_grasps(hand, BOWLS), objects_frame(BOWLS), record(day=2))
    assert folder_bytes(shadow) == before
    other = tmp_path / "three_finger"
    add_batch(other, three_finger_grasps(hand, MUGS), objects_frame(MUGS), record())
    with pytest.raises(DatasetError, match=r"holds grasps of hand .*three_finger.xml, this batch is of hand shadow"):
        add_batch(other, make_grasps(BOWLS), objects_frame(BOWLS), record(day=2))
    with pytest.raises(DatasetError, match="a dataset holds one hand's grasps"):
        merge_datasets([shadow, other], tmp_path / "mixed")


def test_shadow_hand_batches_have_no_hand_members_and_the_repositorys_dataset_loads_as_before(tmp_path):
    dataset = tmp_path / "shadow"
    add_batch(dataset, make_grasps(MUGS), objects_frame(MUGS), record())
    assert not set(HAND_MEMBERS) & set(read_npz(grasps_path(dataset, 1)))
    grasps, _ = load_dataset(dataset)
    assert grasps.attrs == {} and grasps.hand_pose.shape[1] == 28
    from dexlite_pipeline.dataset import write_card

    assert "Grasps of the Shadow Hand on objects" in write_card(dataset, "protocol").read_text()
    if not (REPOSITORY_DATASET / "batches.csv").is_file():
        pytest.skip("no dataset/ in this checkout")
    assert stored_hand(REPOSITORY_DATASET) == {}  # every batch of the campaign: the Shadow Hand's, recorded by no member
    first = load_batch(REPOSITORY_DATASET, 1)
    assert first.attrs == {"batch": "0001"} and first.hand_pose.shape[1] == 28
    assert set(first.arrays) == set(read_npz(grasps_path(REPOSITORY_DATASET, 1))) | {"batch"}


def test_a_run_refuses_a_dataset_of_another_hand(tmp_path, hand):
    import pandas as pd

    from dexlite_pipeline.dataset.for_run import shard_dataset_grasps
    from dexlite_pipeline.objects.assets import CATALOG_NAME

    dataset = tmp_path / "shadow"
    add_batch(dataset, make_grasps(MUGS), objects_frame(MUGS), record())
    objects = tmp_path / "objects"
    objects.mkdir()
    pd.DataFrame({"object_id": MUGS, "split": ["train", "train"], "status": ["ok", "ok"]}).to_parquet(objects / CATALOG_NAME)
    pd.DataFrame({"object_id": MUGS, "stable": [True, True]}).to_parquet(tmp_path / "stability.parquet")
    with pytest.raises(DatasetError, match=r"a dataset of hand shadow, config key hand is .*three_finger.xml: give dataset.root a dataset of"):
        shard_dataset_grasps(dataset, [str(objects)], str(tmp_path / "stability.parquet"), 0, 1, False, hand["hand"])


@pytest.mark.parametrize("hand_name", ["allegro", "leap"])
def test_the_repositorys_dataset_of_another_hand_holds_only_that_hands_grasps(hand_name):
    """dataset-<hand>/ (the campaign's batches of Allegro and LEAP): every batch records the hand and its joints, poses
    of 6 + J numbers, and the card names the hand."""
    from dexlite_pipeline.hand.choice import hand_record

    folder = REPOSITORY_DATASET.parent / f"dataset-{hand_name}"
    if not (folder / "batches.csv").is_file():
        pytest.skip(f"no dataset-{hand_name}/ in this checkout")
    wanted = hand_record(hand_name)
    assert stored_hand(folder) == {"hand": hand_name, "joint_names": list(wanted["joint_names"])}
    grasps, objects = load_dataset(folder)
    assert grasps.hand_pose.shape[1] == 6 + len(wanted["joint_names"]) and len(objects) > 0
    assert set(np.unique(grasps.arrays["object_id"])) <= set(objects["object_id"])
    assert f"Grasps of the hand `{hand_name}`" in (folder / "CARD.md").read_text()
