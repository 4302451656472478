"""Grasp-type conditioning of the CVAE (model.type_condition): the vocabulary a checkpoint records, a checkpoint written
before types loaded unchanged and refused other types, the type the decoder reads, the training mix of ``any``,
and a pinch asked of a model refined as a pinch: only the pinch template's links carry its contacts."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from dexlite_pipeline.energy.config import EnergyConfig
from dexlite_pipeline.energy.grasp_energy import GraspEnergy
from dexlite_pipeline.model.checkpoint import load_checkpoint, save_checkpoint
from dexlite_pipeline.model.config import GRASP_TYPE_NAMES, TrainConfig
from dexlite_pipeline.model.data import build_training_data
from dexlite_pipeline.model.type_condition import GraspTypeRequestError, interleaved_plan, refusal, requested_codes
from dexlite_pipeline.model.training import fit_training_codes, grasp_energy_terms, train_cvae

PINCH_LINKS = {"robot0:thdistal", "robot0:ffdistal", "robot0:mfdistal"}  # optim.grasp_types.PINCH's contact slots


def typed(grasps, types):
    """``grasps`` with ``grasp_type`` cycling through ``types``."""
    grasps.arrays["grasp_type"] = np.resize(np.asarray(types, dtype=object), len(grasps))
    return grasps


def tiny_model_file(grasps, hand, tiny_assets, path, epochs: int = 5):
    """A tiny model trained on ``grasps`` of the sphere and the box, saved to ``path``."""
    data = build_training_data(grasps, tiny_assets, hand)
    energy = GraspEnergy.from_assets(hand, tiny_assets, EnergyConfig(object_point_spacing_m=0.005))
    from dexlite_pipeline.model.config import ModelConfig

    model_config = ModelConfig(pointnet_widths=(16, 32, 64, 32), encoder_hidden=(64, 64), decoder_hidden=(64, 64), latent_dim=8,
                               normalization="none")
    config = TrainConfig(model=model_config, epochs=epochs, max_steps=0, batch_size=8, clouds_per_batch=2, points_per_cloud=64,
                         validation_fraction=0.0)
    everything = np.arange(len(grasps))
    result = train_cvae(data, everything, np.zeros(0, np.int64), config, grasp_energy_terms(energy), seed=0)
    fit_training_codes(result.model, data, everything, config)
    save_checkpoint(path, result.model, config, {"seed": 0}, training_grasps={**grasps.arrays})
    return path


@pytest.fixture(scope="module")
def pre_types_model(hand, tiny_assets, make_grasps, tmp_path_factory):
    """A tiny model trained on grasps without types, its file as checkpoints were written before grasp types existed
    (no ``grasp_types`` entry)."""
    path = tiny_model_file(make_grasps(hand, 16, seed=3), hand, tiny_assets, tmp_path_factory.mktemp("pre_types") / "cvae.pt", epochs=2)
    payload = torch.load(path, map_location="cpu", weights_only=True)
    payload.pop("grasp_types", None)
    torch.save(payload, path)
    return path


@pytest.fixture(scope="module")
def typed_model(hand, tiny_assets, make_grasps, tmp_path_factory):
    """A tiny model trained on power and pinch grasps of the sphere and the box, saved and loaded back."""
    grasps = typed(make_grasps(hand, 16, seed=3), ["power", "pinch", "pinch"])
    return tiny_model_file(grasps, hand, tiny_assets, tmp_path_factory.mktemp("typed_model") / "cvae.pt"), grasps


def test_a_checkpoint_records_its_types_and_codes(typed_model):
    path, grasps = typed_model
    payload = torch.load(path, map_location="cpu", weights_only=True)
    assert payload["grasp_types"] == ["pinch", "power"]  # the training grasps' types, sorted
    assert payload["training_grasps"]["grasp_type"] == grasps.arrays["grasp_type"].tolist()
    model, _ = load_checkpoint(path)
    assert model.type_vocabulary == ("pinch", "power") and model.type_inputs == 2
    assert model.codes_type.tolist() == [0 if t == "pinch" else 1 for t in grasps.arrays["grasp_type"]]
    assert refusal(model.type_vocabulary, "pinch") == "" and "knows only pinch, power grasps" in refusal(model.type_vocabulary, "tripod")


def test_a_model_from_before_grasp_types_loads_unchanged_and_knows_power_only(pre_types_model):
    payload = torch.load(pre_types_model, map_location="cpu", weights_only=True)
    assert "grasp_types" not in payload  # written as before grasp types
    model, _ = load_checkpoint(pre_types_model)
    assert model.type_vocabulary == () and model.type_inputs == 0 and model.grasp_types == ("power",)
    assert set(model.codes_type.tolist()) == {0}
    assert requested_codes(model.type_vocabulary, model.codes_type.numpy(), "any", 5).tolist() == [0] * 5
    with pytest.raises(GraspTypeRequestError, match=r"^the model knows only power grasps \(it was trained without grasp types\); "
                                                    r"it cannot make pinch grasps$"):
        requested_codes(model.type_vocabulary, model.codes_type.numpy(), "pinch", 5)


def test_dexlite_grasp_refuses_a_type_the_model_does_not_know(tmp_path, pre_types_model):
    import trimesh

    from dexlite_pipeline.api import grasp_request
    from dexlite_pipeline.tools.grasp.checks import check_request
    from dexlite_pipeline.tools.grasp.request import GraspToolError

    trimesh.creation.cylinder(radius=0.03, height=0.1).export(tmp_path / "can.obj")
    request = grasp_request([str(tmp_path / "can.obj")], str(tmp_path / "out"), model=str(pre_types_model), evaluator=None, grasp_type="pinch")
    assert request.config["sample"]["grasp_type"] == "pinch"
    assert request.config["optimize_grasps"]["grasp_types"] == {"power": 0.0, "pinch": 1.0, "tripod": 0.0, "lateral": 0.0, "rim": 0.0}
    with pytest.raises(GraspToolError) as refused:
        check_request(request)
    message = str(refused.value)
    assert "\n" not in message and "cvae.pt" in message and "knows only power grasps" in message and "--grasp-type pinch" in message
    with pytest.raises(GraspToolError, match="--grasp-type grip: expected any or one of power, pinch, tripod, lateral"):
        grasp_request([str(tmp_path / "can.obj")], str(tmp_path / "out"), grasp_type="grip")


def test_the_decoder_reads_the_type(typed_model, random_clouds):
    model, _ = load_checkpoint(typed_model[0])
    clouds = random_clouds(1, 64)
    condition = model.condition(clouds, torch.zeros(2, dtype=torch.long), torch.zeros(2, dtype=torch.long))
    anchor = clouds[0, :1, :6].expand(2, 6)
    latent = torch.zeros(2, model.config.latent_dim)
    decoded = model.decode(latent, condition, anchor, torch.tensor([0, 1]))
    assert not torch.allclose(decoded[0], decoded[1])  # same latent and condition, two types: two poses
    with pytest.raises(ValueError, match="conditioned on grasp types"):
        model.decode(latent, condition, anchor)


def test_any_deals_the_training_mix_and_one_type_asks_for_it():
    codes = np.array([1, 1, 0, 1, 1, 1, 0, 1])  # a quarter pinch (column 0), three quarters power
    plan = requested_codes(("pinch", "power"), codes, "any", 8)
    assert plan.tolist() == [1, 0, 1, 1, 1, 0, 1, 1] and (plan == 0).sum() == 2
    assert requested_codes(("pinch", "power"), codes, "pinch", 3).tolist() == [0, 0, 0]
    assert interleaved_plan(np.array([0.5, 0.5]), 4).tolist() == [0, 1, 0, 1]


def test_an_even_mix_proposes_every_type_equally_however_rare_in_training():
    codes = np.array([2] * 97 + [0, 1, 3])  # 97% power (column 2), one lateral, one pinch, one tripod
    vocabulary = ("lateral", "pinch", "power", "tripod")
    training = requested_codes(vocabulary, codes, "any", 8)
    even = requested_codes(vocabulary, codes, "any", 8, mix="even")
    assert np.bincount(training, minlength=4).tolist() == [0, 0, 8, 0]
    assert np.bincount(even, minlength=4).tolist() == [2, 2, 2, 2] and even[:4].tolist() == [0, 1, 2, 3]
    assert requested_codes(vocabulary, codes, "pinch", 3, mix="even").tolist() == [1, 1, 1]  # a named type is that type
    # a model without types knows power only, whatever the mix
    assert requested_codes((), np.zeros(0, np.int64), "any", 3, mix="even").tolist() == [0, 0, 0]


def test_sampled_grasps_decode_from_their_types_codes(typed_model, tiny_assets):
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.latent_codes import code_type_mask
    from dexlite_pipeline.model.sampling import SampleConfig, synthesis_rows

    model, _ = load_checkpoint(typed_model[0])
    mask = code_type_mask(model, np.array([0, 1]))
    assert mask[0].tolist() == (model.codes_type == 0).tolist() and mask[1].tolist() == (model.codes_type == 1).tolist()
    rows = synthesis_rows(model, ObjectClouds(tiny_assets), ["box"], SampleConfig(grasp_type="pinch", yaw_candidates=1), 64,
                          torch.Generator().manual_seed(0), True, "cvae_raw", 6)
    assert rows.types() == ["pinch"] * 6 and torch.isfinite(rows.hand_pose).all()
    mixed = synthesis_rows(model, ObjectClouds(tiny_assets), ["box"], SampleConfig(yaw_candidates=1), 64, torch.Generator().manual_seed(0),
                           True, "cvae_raw", 6)
    assert sorted(mixed.types()) == ["pinch"] * 4 + ["power"] * 2  # the training mix: two pinches to one power grasp


def links_of(hand, contact_index: np.ndarray) -> set[str]:
    names = np.asarray(hand.link_names, dtype=object)
    return set(names[hand.all_contact_link.numpy()[np.asarray(contact_index, dtype=np.int64)]].ravel().tolist())


def test_a_pinch_asked_of_the_model_is_refined_as_a_pinch(typed_model, tiny_assets, hand):
    """``dexlite grasp --grasp-type pinch``'s synthesis: every refined grasp is a pinch, and the links carrying the contacts it
    touches the object with are the pinch template's only; refined without the template the same samples touch with others."""
    from dexlite_pipeline.optim.post import refine
    from dexlite_pipeline.tools.grasp.checks import tool_config
    from dexlite_pipeline.tools.grasp.synthesis import synthesize_with_model

    path, _ = typed_model
    loaded = load_checkpoint(path)
    short = {"annealing": {"iterations": 30}, "budget_iterations": [0, 30], "stop_hopeless": {"iterations": [10, 20, 30]}}
    config, _ = tool_config({"sample": {"grasp_type": "pinch", "yaw_candidates": 1}, "post_optimize": short, "scene": {"table": False}})
    box = [tiny_assets[0]]
    grasps = synthesize_with_model(box, {"box": (0.1,)}, 8, config, loaded, str(path), torch.device("cpu"), seed=0)
    assert grasps.arrays["grasp_type"].tolist() == ["pinch"] * 8
    assert links_of(hand, grasps.arrays["contact_index"]) <= PINCH_LINKS
    # the same starts refined without the pinch's template: the contacts fall on other links too (the check can fail)
    energy = GraspEnergy.from_assets(hand, box, EnergyConfig(weights=config.post_optimize.energy_weights, object_point_spacing_m=0.004))
    free = refine(energy, torch.as_tensor(grasps.arrays["raw_hand_pose"]), torch.zeros(8, dtype=torch.long), torch.full((8,), 0.1),
                  dataclasses.replace(config.post_optimize), torch.Generator().manual_seed(0), "surface")
    assert links_of(hand, free.arrays["contact_index"]) - PINCH_LINKS


def test_the_config_names_the_optimizers_grasp_types():
    from dexlite_pipeline.optim.grasp_types import TYPE_NAMES

    assert GRASP_TYPE_NAMES == TYPE_NAMES
    with pytest.raises(ValueError, match="sample.grasp_type 'grip' is not one of any, power, pinch, tripod, lateral"):
        from dexlite_pipeline.model.config import SampleConfig

        SampleConfig(grasp_type="grip")
