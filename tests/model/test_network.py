"""The network, pose features, associated point and batching: shapes, gradients, invariants."""

import dataclasses
import math

import numpy as np
import pytest
import torch

from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix, rot6d_to_matrix
from dexlite_pipeline.model.association import grasp_rays, nearest_to_ray
from dexlite_pipeline.model.data import cloud_batches, cloud_keys, make_batch, split_validation
from dexlite_pipeline.model.config import ModelConfig
from dexlite_pipeline.model.network import GraspCVAE, kl_divergence
from dexlite_pipeline.model.pose import (
    POSE_FEATURE_DIM,
    features_to_pose,
    pose_to_features,
    reconstruction_error,
    rotate_features,
    turn_stored_poses,
    vertical_rotation,
    shift_translation,
)
from dexlite_pipeline.model.config import TrainConfig
from dexlite_pipeline.model.training import vertical_turns


def test_reference_sizes_give_the_writeup_shapes(random_clouds):
    model = GraspCVAE(ModelConfig(normalization="batch"))
    clouds = random_clouds(3, 128)
    global_feature, per_point = model.pointnet(clouds)
    assert global_feature.shape == (3, 256) and per_point.shape == (3, 128, 256)
    condition = model.condition(clouds, torch.tensor([0, 2, 2, 1]), torch.tensor([0, 5, 127, 64]))
    assert condition.shape == (4, 512)
    anchor = random_clouds(1, 4)[0]  # (4, 6): positions and normals
    mu, log_var = model.encode(torch.randn(4, POSE_FEATURE_DIM), condition, anchor)
    assert mu.shape == log_var.shape == (4, 256)
    assert model.decode(mu, condition, anchor).shape == (4, POSE_FEATURE_DIM)
    assert model.encoder[0].in_features == 28 + 3 + 512  # [q (31 with 6D rotation), c 512]
    convolutions = [m for m in model.pointnet.layers if isinstance(m, torch.nn.Conv1d)]
    assert [m.out_channels for m in convolutions] == [64, 128, 1024, 256] and convolutions[0].in_channels == 6  # xyz + normal
    positions_only = GraspCVAE(ModelConfig(normalization="batch", point_normals=False))
    assert positions_only.pointnet.layers[0].in_channels == 3
    assert positions_only.condition(clouds[..., :3], torch.tensor([0]), torch.tensor([0])).shape == (1, 512)


def test_gradients_reach_every_part(small_model_config, random_clouds):
    torch.manual_seed(0)
    model = GraspCVAE(small_model_config)
    clouds = random_clouds(2, 64)
    condition = model.condition(clouds, torch.tensor([0, 1, 1]), torch.tensor([3, 4, 5]))
    target = torch.randn(3, POSE_FEATURE_DIM)
    decoded, mu, log_var = model(target, condition, random_clouds(1, 3)[0], torch.randn(3, small_model_config.latent_dim))
    (reconstruction_error(decoded, target).mean() + kl_divergence(mu, log_var).mean()).backward()
    for name, part in (("pointnet", model.pointnet), ("encoder", model.encoder), ("decoder", model.decoder)):
        grads = [p.grad for p in part.parameters()]
        assert all(g is not None and torch.isfinite(g).all() for g in grads), name
        assert sum(float(g.abs().sum()) for g in grads) > 0, name


def test_pose_features_round_trip_and_wrap_free_loss():
    pose = torch.zeros(2, 28)
    pose[:, :3] = torch.tensor([[0.1, -0.2, 0.05], [0.0, 0.3, -0.1]])
    pose[:, 3:6] = torch.tensor([[3.1, 0.4, -3.1], [0.2, -1.0, 2.0]])
    pose[:, 6:] = torch.linspace(0, 1, 22)
    back = features_to_pose(pose_to_features(pose))
    assert torch.allclose(back[:, :3], pose[:, :3], atol=1e-6) and torch.allclose(back[:, 6:], pose[:, 6:])
    assert torch.allclose(euler_xyz_to_matrix(back[:, 3:6]), euler_xyz_to_matrix(pose[:, 3:6]), atol=1e-5)
    wrapped = pose.clone()
    wrapped[:, 3] -= 2 * math.pi  # the same rotation, Euler angle wrapped
    assert float(reconstruction_error(pose_to_features(wrapped), pose_to_features(pose)).max()) < 1e-10
    turned = pose.clone()
    turned[:, 5] += 0.5
    assert float(reconstruction_error(pose_to_features(turned), pose_to_features(pose)).min()) > 1e-3


def test_kl_is_zero_at_the_prior_only():
    assert float(kl_divergence(torch.zeros(1, 4), torch.zeros(1, 4))) == 0.0
    assert float(kl_divergence(torch.ones(1, 4), torch.zeros(1, 4))) == pytest.approx(2.0)


def test_batchnorm_needs_several_clouds_per_batch():
    with pytest.raises(ValueError, match="clouds_per_batch"):
        TrainConfig(clouds_per_batch=1, model=ModelConfig(normalization="batch"))
    TrainConfig(clouds_per_batch=2, model=ModelConfig(normalization="batch"))


def _with_normals(points: torch.Tensor, normals: torch.Tensor) -> torch.Tensor:
    return torch.cat([points, torch.nn.functional.normalize(normals, dim=-1)], dim=-1)


def test_associated_point_is_the_point_nearest_the_ray():
    points = torch.tensor([[[0.0, 0.0, -1.0], [1.0, 0.5, 0.0], [2.0, 0.1, 0.0], [0.5, 2.0, 0.0]]])
    cloud = _with_normals(points, -torch.ones_like(points))  # every normal faces back toward the origin
    origin, direction = torch.zeros(1, 3), torch.tensor([[1.0, 0.0, 0.0]])
    assert int(nearest_to_ray(cloud, origin, direction)) == 2  # point behind the origin does not count


def test_associated_point_is_on_the_side_of_the_object_the_hand_is_on():
    # A unit sphere's surface; the ray from x = -3 goes through its centre, so points of the
    # far side (x ~ +1) lie as close to it as those of the near side (x ~ -1).
    generator = torch.Generator().manual_seed(0)
    points = torch.nn.functional.normalize(torch.randn(1, 2000, 3, generator=generator), dim=-1)
    cloud = _with_normals(points, points)
    origin, direction = torch.tensor([[-3.0, 0.0, 0.0]]), torch.tensor([[1.0, 0.0, 0.0]])
    chosen = cloud[0, int(nearest_to_ray(cloud, origin, direction))]
    assert float(chosen[0]) < -0.95
    far_only = cloud[:, cloud[0, :, 0] > 0]  # no point faces the ray: the nearest of all is taken
    assert float(far_only[0, int(nearest_to_ray(far_only, origin, direction)), 0]) > 0.95
    with pytest.raises(ValueError, match="normals"):
        nearest_to_ray(points, origin, direction)


def test_grasp_ray_points_from_the_palm_toward_the_fingertips(hand, make_grasps):
    grasps = make_grasps(hand, 8, seed=0)
    origin, direction = grasp_rays(hand, torch.as_tensor(grasps.hand_pose))
    # For poses built with the object in front of the palm, the ray passes near the object centre.
    along = (-origin * direction).sum(-1)
    off_ray = (-origin - along[:, None] * direction).norm(dim=-1)
    assert bool((along > 0).all()) and bool((off_ray < torch.as_tensor(grasps.scale)).all())
    assert torch.allclose(direction.norm(dim=-1), torch.ones(8))


def test_cloud_batches_cover_each_grasp_once_with_few_clouds_each():
    object_id = np.array(["a"] * 10 + ["b"] * 7 + ["c"] * 3, dtype=object)
    scale = np.array([0.1] * 5 + [0.08] * 5 + [0.1] * 10, dtype=np.float32)
    keys = cloud_keys(object_id, scale)
    assert len(set(keys.tolist())) == 4
    batches = cloud_batches(keys, np.arange(20), batch_size=8, clouds_per_batch=2, rng=np.random.default_rng(0))
    seen = np.concatenate([np.concatenate(chunks) for chunks in batches])
    assert sorted(seen.tolist()) == list(range(20))
    for chunks in batches:
        assert len(chunks) <= 2 and all(len(set(keys[c].tolist())) == 1 and len(c) <= 4 for c in chunks)
        batch = make_batch(chunks, keys, np.zeros(20, np.int64), scale, "cpu")
        assert len(batch.cloud_object) == len(set(keys[batch.grasp_index].tolist()))
        assert torch.equal(torch.as_tensor(keys[batch.grasp_index]), torch.as_tensor(np.unique(keys[batch.grasp_index]))[batch.cloud_index])


def test_cloud_batches_hold_distinct_clouds_while_several_are_left():
    # One big cloud (100 grasps) and a small one (10): chunks of 32 are 4 of the big cloud, 1 of the small.
    keys = np.array([0] * 100 + [1] * 10)
    for seed in range(5):
        batches = cloud_batches(keys, np.arange(110), batch_size=64, clouds_per_batch=2, rng=np.random.default_rng(seed))
        clouds = [[int(keys[chunk[0]]) for chunk in chunks] for chunks in batches]
        assert sum(len(c) == 2 for c in clouds) == 1 and all(len(set(c)) == len(c) for c in clouds)
        assert sorted(np.concatenate([np.concatenate(chunks) for chunks in batches]).tolist()) == list(range(110))


def test_validation_split_is_seeded_and_disjoint():
    train, val = split_validation(50, 0.2, seed=3)
    assert len(val) == 10 and not set(train) & set(val) and len(train) + len(val) == 50
    assert np.array_equal(split_validation(50, 0.2, seed=3)[1], val)


def test_turning_a_grasp_turns_the_hand_with_the_object(hand):
    torch.manual_seed(3)
    pose = torch.cat([torch.randn(4, 3) * 0.1, torch.randn(4, 3), torch.rand(4, 22) * 0.5], dim=1)
    turn = vertical_turns(4, torch.Generator().manual_seed(0), torch.device("cpu"))
    assert torch.allclose(turn[:, 2], torch.tensor([0.0, 0.0, 1.0]).expand(4, 3))  # the vertical axis stays put
    turned = features_to_pose(rotate_features(pose_to_features(pose), turn))
    links, turned_links = hand.forward(pose).translation, hand.forward(turned).translation
    assert torch.allclose(turned_links, links @ turn.transpose(1, 2), atol=1e-5)
    back = rotate_features(pose_to_features(turned), turn.transpose(1, 2))
    assert torch.allclose(features_to_pose(back)[:, :3], pose[:, :3], atol=1e-6)


def test_turning_a_stored_pose_about_z_matches_turning_its_features(hand):
    """turn_stored_poses (the evaluator's augmentation, on stored Euler poses) and rotate_features (the model's) agree, and
    the whole hand turns with the object."""
    torch.manual_seed(4)
    pose = torch.cat([torch.randn(6, 3) * 0.1, torch.rand(6, 3) * 6 - 3, torch.rand(6, 22) * 0.5], dim=1)
    angle = torch.rand(6) * 2 * math.pi
    turned = turn_stored_poses(pose, angle)
    turn = vertical_rotation(angle)
    expected = rotate_features(pose_to_features(pose), turn)
    assert torch.allclose(pose_to_features(turned), expected, atol=1e-5)
    assert bool((turned[:, 5] > -math.pi).all() and (turned[:, 5] <= math.pi).all())  # the z angle stays in range
    links, turned_links = hand.forward(pose).translation, hand.forward(turned).translation
    assert torch.allclose(turned_links, links @ turn.transpose(1, 2), atol=1e-5)


def test_point_frame_moves_the_palm_with_the_associated_point(small_model_config):
    torch.manual_seed(0)
    model = GraspCVAE(dataclasses.replace(small_model_config, pose_frame="point"))
    condition, latent = torch.randn(2, small_model_config.condition_dim), torch.randn(2, small_model_config.latent_dim)
    anchor, shift = torch.randn(2, 6) * 0.1, torch.tensor([[0.01, -0.02, 0.03, 0, 0, 0], [0.0, 0.05, 0.0, 0, 0, 0]])
    with torch.no_grad():
        here, there = model.decode(latent, condition, anchor), model.decode(latent, condition, anchor + shift)
        pose = torch.randn(2, POSE_FEATURE_DIM)
        mu, _ = model.encode(pose, condition, anchor)
        mu_shifted, _ = model.encode(shift_translation(pose, shift[:, :3]), condition, anchor + shift)
    assert torch.allclose(features_to_pose(there)[:, :3] - features_to_pose(here)[:, :3], shift[:, :3], atol=1e-6)
    assert torch.allclose(there[:, 3:], here[:, 3:]) and torch.allclose(mu, mu_shifted, atol=1e-6)


def test_surface_frame_turns_the_grasp_with_the_surface(small_model_config):
    """Turning the associated point and its normal about the vertical axis turns the decoded grasp with them."""
    torch.manual_seed(0)
    model = GraspCVAE(small_model_config)
    assert small_model_config.pose_frame == "surface"
    normal = torch.nn.functional.normalize(torch.tensor([[1.0, 0.2, 0.3], [-0.3, 1.0, -0.5], [0.05, 0.0, 1.0]]), dim=-1)
    anchor = torch.cat([torch.randn(3, 3) * 0.1, normal], dim=1)
    turn = vertical_turns(3, torch.Generator().manual_seed(1), torch.device("cpu"))
    turned_anchor = torch.cat([(turn @ anchor[:, :3, None])[..., 0], (turn @ anchor[:, 3:, None])[..., 0]], dim=1)
    condition, latent = torch.randn(3, small_model_config.condition_dim), torch.randn(3, small_model_config.latent_dim)
    with torch.no_grad():
        decoded, decoded_turned = model.decode(latent, condition, anchor), model.decode(latent, condition, turned_anchor)
        pose = pose_to_features(torch.cat([torch.randn(3, 3) * 0.1, torch.randn(3, 3), torch.rand(3, 22)], dim=1))
        mu, _ = model.encode(pose, condition, anchor)
        mu_turned, _ = model.encode(rotate_features(pose, turn), condition, turned_anchor)
    # The first two grasps turn exactly; the third's normal is near vertical, where the frame's tangent is the object's x axis.
    assert torch.allclose(rotate_features(decoded, turn)[:2], decoded_turned[:2], atol=1e-5)
    assert torch.allclose(mu[:2], mu_turned[:2], atol=1e-5)
    assert torch.isfinite(decoded_turned[2]).all()


def test_hand_frame_takes_the_roll_from_the_grasp_and_draws_it_for_new_grasps(small_model_config):
    """In the ``hand`` frame a grasp's palm lateral axis has no component along the frame's z; sampled rolls are tangent and varied."""
    torch.manual_seed(0)
    model = GraspCVAE(dataclasses.replace(small_model_config, pose_frame="hand"))
    normal = torch.nn.functional.normalize(torch.randn(5, 3), dim=-1)
    anchor = torch.cat([torch.randn(5, 3) * 0.1, normal], dim=1)
    pose = pose_to_features(torch.cat([torch.randn(5, 3) * 0.1, torch.randn(5, 3), torch.rand(5, 22)], dim=1))
    full = model.pose_anchors(anchor, pose)
    assert full.shape == (5, 9)
    in_frame = model._to_frame(pose, full)
    lateral_in_frame = rot6d_to_matrix(in_frame[:, 3:9])[:, :, 0]
    assert torch.allclose(lateral_in_frame[:, 2], torch.zeros(5), atol=1e-5)  # roll fixed by the grasp
    assert torch.allclose(model._from_frame(in_frame, full), pose, atol=1e-5)
    drawn = model.sampling_anchors(anchor, torch.Generator().manual_seed(0))
    again = model.sampling_anchors(anchor, torch.Generator().manual_seed(0))
    assert torch.equal(drawn, again) and torch.equal(drawn[:, :6], anchor)
    assert torch.allclose((drawn[:, 6:] * normal).sum(-1), torch.zeros(5), atol=1e-6)
    assert torch.allclose(drawn[:, 6:].norm(dim=-1), torch.ones(5), atol=1e-6)
    assert len(set(torch.round(drawn[:, 6], decimals=3).tolist())) == 5
    with pytest.raises(ValueError, match="lateral"):
        model.decode(torch.randn(5, small_model_config.latent_dim), torch.randn(5, small_model_config.condition_dim), anchor)


def test_hand_frame_networks_read_the_roll(small_model_config):
    """The same latent and condition decode to differently turned grasps at two rolls, which the networks are told."""
    torch.manual_seed(0)
    model = GraspCVAE(dataclasses.replace(small_model_config, pose_frame="hand"))
    anchor = torch.tensor([[0.1, 0.0, 0.0, 1.0, 0.0, 0.0]])
    up, side = torch.cat([anchor, torch.tensor([[0.0, 0.0, 1.0]])], 1), torch.cat([anchor, torch.tensor([[0.0, 1.0, 0.0]])], 1)
    assert torch.allclose(model._inputs(torch.zeros(1, 0), up), torch.tensor([[0.0, 1.0, 0.0]]), atol=1e-6)
    assert torch.allclose(model._inputs(torch.zeros(1, 0), side), torch.tensor([[0.0, 0.0, 1.0]]), atol=1e-6)
    latent, condition = torch.randn(1, small_model_config.latent_dim), torch.randn(1, small_model_config.condition_dim)
    with torch.no_grad():
        assert not torch.allclose(model.decode(latent, condition, up), model.decode(latent, condition, side), atol=1e-3)
