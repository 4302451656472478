"""The shipped models (src/dexlite_pipeline/data/<hand>-hand-household/, model.shipped.SHIPPED_MODEL_DIRS; the Shadow Hand's
always, another hand's when its folder ships): each loads weights-only as its hand's, its card describes it, its evaluator
loads, and on a few freshly rebuilt objects its check agrees with the card within sampling noise."""

import dataclasses
import json
import math

import pytest
import torch

from dexlite_pipeline.model.shipped import SHIPPED_MODEL_DIRS, SHIPPED_MODEL_PATH, shipped_model_path
from dexlite_pipeline.model.shipped_check import shipped_model_check

CHECK_SECTIONS = ("seed", "lift", "sample")  # what shipped_model_check reads of its config
SHIPPED_HANDS = [hand for hand in SHIPPED_MODEL_DIRS if hand == "shadow" or shipped_model_path(hand) is not None]


@pytest.fixture(scope="module", params=SHIPPED_HANDS)
def shipped(request):
    """(hand, model file, card) of each shipped model; the Shadow Hand's must be there."""
    path = shipped_model_path(request.param)
    assert path is not None, f"{SHIPPED_MODEL_PATH} is missing: the repository ships it"
    return request.param, path, json.loads(path.with_name("card.json").read_text())


def test_shipped_model_loads_weights_only_and_matches_its_card(shipped):
    from dexlite_pipeline.hand.choice import hand_record
    from dexlite_pipeline.model.checkpoint import load_checkpoint

    hand, path, card = shipped
    assert (card.get("hand") or {"name": "shadow"})["name"] == hand
    payload = torch.load(path, map_location="cpu", weights_only=True)
    assert payload["format"] == "dexlite-cvae-1" and payload["stored_dtype"] == "float16"
    assert path.stat().st_size / 1e6 == pytest.approx(card["file_megabytes"], rel=1e-6)
    # It lives in the repository: float16 weights and latent codes (one per training grasp, or at most the card's
    # codes_kept cap per training cloud, so the size stops growing with the grasps per object) and the training grasps,
    # nothing else; below the 50 MB a git host takes without large-file storage.
    stored = sum(v.numel() * v.element_size() for v in payload["state_dict"].values())
    stored += sum(v.numel() * 4 for v in payload["training_grasps"].values() if isinstance(v, torch.Tensor))  # not the ids' and types' strings
    assert path.stat().st_size < 1.05 * stored + 2e6
    assert path.stat().st_size < 50e6
    training = card["training"]
    assert payload["train_grasps"] == training["train_grasps"] and payload["steps"] == training["steps"]
    assert len(payload["train_object_ids"]) == training["train_objects"] and len(payload["training_grasps"]["object_id"]) == training["train_grasps"]
    from dexlite_pipeline.objects.sources import benchmark_object_ids, household_benchmark_list

    assert not set(payload["train_object_ids"]) & (benchmark_object_ids() | set(household_benchmark_list()))  # never on a held-out split
    model, _ = load_checkpoint(path, hand=hand_record(hand))  # a model of its hand
    kept = card.get("codes_kept")  # None: every training grasp kept its code
    assert payload.get("codes_kept") == kept
    assert kept is None or (kept["before"] == training["train_grasps"] and kept["after"] <= kept["before"])
    assert all(p.dtype == torch.float32 for p in model.parameters()) and len(model.codes_mu) == (kept["after"] if kept else training["train_grasps"])
    from dexlite_pipeline.io.grasp_store import read_grasp_store

    dataset = read_grasp_store(path.with_name("training_grasps.zarr"))  # the training data, beside the model
    assert dataset.hand_pose.tolist() == payload["training_grasps"]["hand_pose"].tolist()
    assert dataset.object_id.tolist() == payload["training_grasps"]["object_id"]


def test_the_shipped_evaluator_loads_and_never_trained_on_a_held_out_split(shipped):
    from dexlite_pipeline.hand.choice import hand_record
    from dexlite_pipeline.model.evaluator import load_evaluator
    from dexlite_pipeline.model.shipped import shipped_evaluator_path
    from dexlite_pipeline.objects.sources import benchmark_object_ids, household_benchmark_list

    hand, _, card = shipped
    path = shipped_evaluator_path(hand)
    assert path is not None and card["evaluator"] is not None  # the shipped model's samples are ranked by its own evaluator
    _, meta = load_evaluator(path, hand=hand_record(hand))
    trained_on = set(meta["train_object_ids"])
    assert len(trained_on) == card["evaluator"]["train_objects"]
    assert not trained_on & (benchmark_object_ids() | set(household_benchmark_list()))


def _within_sampling_noise(successes_a: int, successes_b: int, count: int) -> bool:
    """Two lift-success counts of ``count`` grasps each agree within 3 standard deviations of their difference."""
    pooled = (successes_a + successes_b) / (2 * count)
    spread = math.sqrt(2 * pooled * (1 - pooled) / count)
    return abs(successes_a - successes_b) / count <= 3 * spread + 1 / count


@pytest.mark.slow
def test_shipped_model_repeats_its_card_on_freshly_prepared_objects(shipped, tmp_path):
    """Fit errors on training objects and raw lift success on benchmark objects, as the card's check measured them."""
    from dexlite_pipeline.config import from_section
    from dexlite_pipeline.objects.config import ObjectsConfig
    from dexlite_pipeline.objects.prepare import prepare_objects
    from dexlite_pipeline.objects.sources import rebuilt_source_of
    from dexlite_pipeline.settings import build_config

    hand, path, card = shipped
    expected = card["check"]["shipped"]
    train_ids, heldout_ids = expected["fit"]["objects"], expected["heldout_raw"]["objects"]
    # The card records the whole config of the code version that made the model (keys since renamed or removed
    # included); the check reads the sections below, so only they are rebuilt with today's types.
    config = build_config({name: card["config"][name] for name in CHECK_SECTIONS})
    # held out as in the run, so prepared at the same seeded yaw when the run turned its held-out objects (objects.heldout_yaw;
    # a card without the key predates the turn)
    sources = [rebuilt_source_of(oid, tmp_path / "meshes") for oid in train_ids]
    sources += [dataclasses.replace(rebuilt_source_of(oid, tmp_path / "meshes"), always_heldout=True) for oid in heldout_ids]
    objects = from_section(ObjectsConfig, {"heldout_yaw": False, **card["config"].get("objects", {})}, "card.objects")
    catalog = prepare_objects(sources, tmp_path, objects, config.seed, workers=2)
    assert (catalog["status"] == "ok").all()

    got = shipped_model_check(path, [str(tmp_path)], train_ids, heldout_ids, config, expected["heldout_raw"]["grasps_per_object"],
                              threads=card["check"]["threads"], seed=card["check"]["seed"])  # fmt: skip
    fit, card_fit = got["fit"], expected["fit"]
    assert fit["grasps"] == card_fit["grasps"]
    assert fit["rotation_error_deg_median"] == pytest.approx(card_fit["rotation_error_deg_median"], rel=0.1, abs=0.3)
    assert fit["translation_error_mm_median"] == pytest.approx(card_fit["translation_error_mm_median"], rel=0.1, abs=0.5)
    assert fit["joint_error_rad_mean"] == pytest.approx(card_fit["joint_error_rad_mean"], rel=0.1, abs=0.005)
    raw, card_raw = got["heldout_raw"], expected["heldout_raw"]
    assert raw["grasps"] == card_raw["grasps"]
    assert _within_sampling_noise(raw["lift_successes"], card_raw["lift_successes"], raw["grasps"]), (raw, card_raw)


def test_each_hand_has_its_own_shipped_folder_and_a_hand_from_a_file_has_none(tmp_path):
    from dexlite_pipeline.hand.choice import hand_record
    from dexlite_pipeline.model.checkpoint import load_checkpoint
    from dexlite_pipeline.model.shipped import SHIPPED_MODEL_DIRS, missing_shipped_model_reason, model_or_shipped

    assert shipped_model_path("shadow") == shipped_model_path() == SHIPPED_MODEL_PATH
    mjcf = str(tmp_path / "hand.xml")
    assert shipped_model_path(mjcf) is None
    with pytest.raises(FileNotFoundError, match=f"no --model given and no model ships for hand {mjcf}"):
        model_or_shipped(None, mjcf)
    for hand in ("allegro", "leap"):
        path = shipped_model_path(hand)
        if path is None:
            assert f"{SHIPPED_MODEL_DIRS[hand]}/cvae.pt (not shipped for hand {hand}" in missing_shipped_model_reason(hand)
            continue
        assert path.parent.name == f"{hand}-hand-household" and model_or_shipped(None, hand) == path
        model, _ = load_checkpoint(path, hand=hand_record(hand))  # a model of that hand: refused for any other
        assert model.pose_width == 6 + len(hand_record(hand)["joint_names"])
