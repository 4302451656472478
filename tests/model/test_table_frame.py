"""The generator's table frame: clouds turned so the table's normal is +z, grasps turned back into the object's frame."""

import dataclasses
import math

import numpy as np
import pytest
import torch

from dexlite_pipeline.model.table_frame import upright_rotation, upright_rotations
from dexlite_pipeline.objects.rest_pose import SupportPlane
from dexlite_pipeline.tabletop import SupportPlanes


def _is_rotation(matrix: np.ndarray) -> bool:
    return np.allclose(matrix @ matrix.T, np.eye(3), atol=1e-12) and math.isclose(np.linalg.det(matrix), 1.0, abs_tol=1e-12)


@pytest.mark.parametrize("normal", [(1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.3, -0.2, 0.9), (0.1, 0.2, -0.97), (0.0, 0.0, -1.0), (2.0, 0.0, 0.0)])
def test_upright_rotation_takes_the_table_normal_to_plus_z(normal):
    rotation = upright_rotation(normal)
    assert _is_rotation(rotation)
    assert rotation @ (np.asarray(normal) / np.linalg.norm(normal)) == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)


def test_upright_rotation_is_the_smallest_turn():
    """A normal tilted 30 deg from +z about x is turned back by 30 deg about x, nothing more (no turn about the vertical)."""
    tilt = math.radians(30.0)
    normal = (0.0, -math.sin(tilt), math.cos(tilt))
    rotation = upright_rotation(normal)
    assert math.degrees(math.acos((np.trace(rotation) - 1.0) / 2.0)) == pytest.approx(30.0)
    assert rotation @ np.array([1.0, 0.0, 0.0]) == pytest.approx([1.0, 0.0, 0.0])


@pytest.mark.parametrize("normal", [(0.0, 0.0, 1.0), (math.nan, 0.0, 1.0), (0.0, 0.0, 0.0)])
def test_no_turn_for_an_upright_object_or_without_a_table(normal):
    assert np.array_equal(upright_rotation(normal), np.eye(3))


def test_objects_without_a_plane_keep_their_frame():
    planes = SupportPlanes({"lying": SupportPlane((1.0, 0.0, 0.0), 0.5)})
    rotations = upright_rotations(["standing", "lying"], planes)
    assert torch.equal(rotations[0], torch.eye(3))
    assert rotations[1] @ torch.tensor([1.0, 0.0, 0.0]) == pytest.approx(torch.tensor([0.0, 0.0, 1.0]), abs=1e-6)
    assert torch.equal(upright_rotations(["lying"], None)[0], torch.eye(3))


def _with_codes_on(model, clouds: torch.Tensor) -> None:
    with torch.no_grad():
        global_feature, per_point = model.pointnet(clouds)
    latent = model.config.latent_dim
    model.set_latent_codes(torch.zeros(len(clouds), latent), torch.zeros(len(clouds), latent),
                           torch.cat([global_feature, per_point[:, 0]], 1), torch.arange(len(clouds)))


def test_grasps_of_an_object_lying_on_its_side_are_its_upright_grasps_turned(small_model_config, tiny_assets):
    """The same object in a file tipped 90 deg about x, resting with the file's -y up: sampled with its table, the model
    reads the same cloud as of the upright file and returns the same grasps, turned with the object; read in the
    file's own frame (no table known) it returns others."""
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.network import GraspCVAE
    from dexlite_pipeline.model.sampling import synthesize

    torch.manual_seed(2)
    model = GraspCVAE(small_model_config).eval()
    asset = tiny_assets[0]
    tip = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # 90 deg about x: the file's +z becomes -y
    tipped = dataclasses.replace(asset, object_id="tipped", surface_points=(asset.surface_points @ tip.T).astype(np.float32),
                                 surface_normals=(asset.surface_normals @ tip.T).astype(np.float32))
    planes = SupportPlanes({asset.object_id: SupportPlane((0.0, 0.0, 1.0), 0.5), "tipped": SupportPlane(tuple(tip @ [0.0, 0.0, 1.0]), 0.5)})
    clouds = ObjectClouds([asset, tipped], planes=planes)
    _with_codes_on(model, clouds.draw_fixed(torch.tensor([0]), torch.tensor([0.1]), 64))
    scale = np.full(4, 0.1, np.float32)

    def sampled(on: ObjectClouds, index: int) -> torch.Tensor:
        with torch.no_grad():
            return synthesize(model, on, np.full(4, index, np.int64), scale, 64, torch.Generator().manual_seed(3), "aggregate", 1.0, True, "uniform")

    hand = ShadowHand()
    upright_links = hand.forward(sampled(clouds, 0)).translation
    tipped_links = hand.forward(sampled(clouds, 1)).translation
    assert torch.allclose(tipped_links, upright_links @ torch.as_tensor(tip, dtype=torch.float32).T, atol=1e-4)
    unknown_table = hand.forward(sampled(ObjectClouds([asset, tipped]), 1)).translation
    assert not torch.allclose(unknown_table, tipped_links, atol=1e-3)


def test_training_reads_a_lying_object_as_its_upright_twin(hand, small_model_config, tiny_assets, make_grasps):
    """Grasps of the box and of the same box in a tipped file (its grasps tipped with it, its table recorded in the
    store as the grasps' ``support_normal``): the training loss reads both in the table frame, so it is the same."""
    from dexlite_pipeline.energy.config import EnergyWeights
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.model.config import TrainConfig
    from dexlite_pipeline.model.data import build_training_data, make_batch
    from dexlite_pipeline.model.network import GraspCVAE
    from dexlite_pipeline.model.pose import features_to_pose, pose_to_features, rotate_features
    from dexlite_pipeline.model.training import batch_loss

    box = tiny_assets[0]
    tip = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    tipped = dataclasses.replace(box, object_id="tipped", surface_points=(box.surface_points @ tip.T).astype(np.float32),
                                 surface_normals=(box.surface_normals @ tip.T).astype(np.float32))
    grasps = make_grasps(hand, 8, seed=4)
    on_box = np.flatnonzero(np.asarray(grasps.object_id).astype(str) == box.object_id)
    pose = torch.as_tensor(grasps.hand_pose[on_box], dtype=torch.float32)
    turned = features_to_pose(rotate_features(pose_to_features(pose), torch.as_tensor(tip, dtype=torch.float32).expand(len(pose), 3, 3)))

    def store(object_id: str, poses: torch.Tensor, normal) -> GraspSet:
        count = len(poses)
        return GraspSet({"hand_pose": poses.numpy(), "object_id": np.full(count, object_id, dtype=object),
                         "scale": np.full(count, 0.1, np.float32), "support_normal": np.tile(np.asarray(normal, np.float32), (count, 1)),
                         "support_offset_m": np.full(count, 0.05, np.float32)}, {})

    upright = build_training_data(store(box.object_id, pose, (0.0, 0.0, 1.0)), [box], hand)
    lying = build_training_data(store("tipped", turned, tip @ [0.0, 0.0, 1.0]), [tipped], hand)
    assert lying.clouds.upright[0] @ torch.tensor(tip[:, 2], dtype=torch.float32) == pytest.approx(torch.tensor([0.0, 0.0, 1.0]), abs=1e-6)
    torch.manual_seed(0)
    model = GraspCVAE(small_model_config).eval()
    weights = TrainConfig(model=small_model_config, energy_weights=EnergyWeights(0.0, 0.0, 0.0, 0.0, 0.0)).weights(False)
    losses = []
    for data in (upright, lying):
        batch = make_batch([np.arange(len(pose))], data.cloud_key, data.object_index, data.scale, "cpu")
        with torch.no_grad():
            _, terms = batch_loss(model, data, batch, 64, None, weights, torch.Generator().manual_seed(1), fixed_clouds=True)
        losses.append(terms)
    assert losses[1]["recon"] == pytest.approx(losses[0]["recon"], rel=1e-4)
    assert losses[1]["kl"] == pytest.approx(losses[0]["kl"], rel=1e-4)
