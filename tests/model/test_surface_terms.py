"""The loss terms read off the surface samples: which samples the penetration finds inside the hand, how it grows with
depth, its gradient; the pads' heights against the training grasp's; a training run with both and no mesh energy."""

import dataclasses

import numpy as np
import pytest
import torch

from dexlite_pipeline.energy.config import EnergyConfig
from dexlite_pipeline.energy.grasp_energy import GraspEnergy
from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix
from dexlite_pipeline.model.config import SURFACE_DISTANCE_TERM, SURFACE_PENETRATION_TERM, TrainConfig
from dexlite_pipeline.model.data import ObjectClouds, build_training_data
from dexlite_pipeline.model.surface_terms import samples_inside_hand, surface_terms
from dexlite_pipeline.model.trainer import unbuilt_energy_terms, uses_energies
from dexlite_pipeline.model.training import train_cvae, with_surface_terms


@pytest.fixture(scope="module")
def poses(hand, make_grasps, tiny_assets):
    """Poses facing the sphere, the palm about 1.5 cm off its surface with the fingers half closed around it (the
    box's faces lie centimetres further from the palm, depending on its turn)."""
    grasps = make_grasps(hand, 24, seed=3)
    grasps = grasps.select(grasps.object_id == "sphere")
    index = torch.as_tensor([[a.object_id for a in tiny_assets].index(o) for o in grasps.object_id])
    return torch.as_tensor(grasps.hand_pose, dtype=torch.float32), index, torch.as_tensor(grasps.scale, dtype=torch.float32)


def _moved(pose: torch.Tensor, scale: torch.Tensor, toward_object_m: float) -> torch.Tensor:
    """The poses moved along the palm's -y axis (towards the object the fingers face) by ``toward_object_m``."""
    rotation = euler_xyz_to_matrix(pose[:, 3:6])
    moved = pose.clone()
    moved[:, :3] = pose[:, :3] - rotation[:, :, 1] * toward_object_m
    return moved


def _parts(pose):
    return euler_xyz_to_matrix(pose[:, 3:6]), pose[:, :3], pose[:, 6:]


def _term(hand, tiny_assets, pose, index, scale, name=SURFACE_PENETRATION_TERM, target=None):
    terms = surface_terms(hand, ObjectClouds(tiny_assets), (name,))
    return terms(*_parts(pose), index, scale, _parts(pose if target is None else target))[name]


def test_the_culled_search_finds_exactly_the_samples_inside_the_hand(hand, tiny_assets, poses):
    pose, index, scale = poses
    clouds = ObjectClouds(tiny_assets)
    for depth in (0.0, 0.01, 0.03):
        moved = _moved(pose, scale, depth)
        frames = hand.forward(moved)
        samples = clouds.surface[index] * scale[:, None, None]
        rot, centre = hand.shape_frames(frames)
        grasp, sample = samples_inside_hand(hand, rot, centre, samples)
        brute = torch.nonzero(hand.collision_signed_distance(frames, samples) > 0)
        assert sorted(zip(grasp.tolist(), sample.tolist())) == sorted(map(tuple, brute.tolist()))
    assert len(grasp) > 0  # 3 cm into the object: some samples are inside


def test_the_term_is_zero_away_from_the_object_and_grows_as_the_hand_goes_in(hand, tiny_assets, poses):
    pose, index, scale = poses
    away = _term(hand, tiny_assets, _moved(pose, scale, -0.3), index, scale)
    assert torch.equal(away, torch.zeros_like(away))
    values = torch.stack([_term(hand, tiny_assets, _moved(pose, scale, d), index, scale) for d in (0.0, 0.005, 0.01, 0.015)])
    assert (values[1:] >= values[:-1] - 1e-6).all()  # per grasp, deeper is more
    assert (values[-1] > values[0]).all()
    # it agrees with the mesh energy's judged depth on which poses penetrate
    energy = GraspEnergy.from_assets(hand, tiny_assets, EnergyConfig(object_point_spacing_m=0.005))
    deep = _moved(pose, scale, 0.015)
    judged = energy.judged_depth_m(hand.forward(deep), index, scale)
    assert (judged > 0.005).all() and (values[-1] > 0.005).all()


def test_a_step_against_its_gradient_takes_the_hand_out(hand, tiny_assets, poses):
    pose, index, scale = poses
    deep = _moved(pose, scale, 0.02).requires_grad_(True)
    value = _term(hand, tiny_assets, deep, index, scale)
    value.sum().backward()
    step = deep.detach() - 1e-3 * deep.grad / deep.grad.norm(dim=1, keepdim=True).clamp(min=1e-12)
    assert (_term(hand, tiny_assets, step, index, scale) < value.detach()).float().mean() > 0.9


def test_the_pad_heights_match_at_the_training_grasp_and_grow_either_way(hand, tiny_assets, poses):
    pose, index, scale = poses
    at_target = _term(hand, tiny_assets, pose, index, scale, SURFACE_DISTANCE_TERM, target=pose)
    assert torch.equal(at_target, torch.zeros_like(at_target))
    for offset in (-0.01, 0.01):  # too far and too deep alike; a pad's height changes by at most the 1 cm it moved (1 cm²)
        moved = _term(hand, tiny_assets, _moved(pose, scale, offset), index, scale, SURFACE_DISTANCE_TERM, target=pose)
        assert ((moved > 0.1) & (moved <= 1.0 + 1e-4)).all(), moved
    with pytest.raises(ValueError, match="unknown surface terms"):
        surface_terms(hand, ObjectClouds(tiny_assets), ("surface_fc",))


def test_training_with_them_builds_no_mesh_energy_and_logs_them(hand, tiny_assets, make_grasps, small_model_config):
    grasps = make_grasps(hand, 8, seed=1)
    data = build_training_data(grasps, tiny_assets, hand)
    config = TrainConfig(model=small_model_config, epochs=20, max_steps=0, batch_size=8, clouds_per_batch=2, points_per_cloud=64,
                         learning_rate=3e-3, validation_fraction=0.0, energy_warmup_fraction=0.0, weight_surface_penetration=10.0,
                         weight_surface_distance=1.0)
    assert not uses_energies(config, table=True) and config.surface_terms() == (SURFACE_PENETRATION_TERM, SURFACE_DISTANCE_TERM)
    assert dataclasses.replace(config, weight_surface_penetration=0.0).surface_terms() == (SURFACE_DISTANCE_TERM,)
    terms = with_surface_terms(unbuilt_energy_terms, surface_terms(hand, data.clouds, config.surface_terms()), mesh=False)
    result = train_cvae(data, np.arange(len(grasps)), np.zeros(0, np.int64), config, terms, seed=0)
    first, last = result.history[0], result.history[-1]
    assert all(np.isnan(last[f"train_{k}"]) for k in ("fc", "pen"))
    for term in (SURFACE_PENETRATION_TERM, SURFACE_DISTANCE_TERM):
        assert np.isfinite(last[f"train_{term}"]) and last[f"train_{term}"] < first[f"train_{term}"]


def test_kept_nearest_samples_give_the_searched_values_and_gradients(hand, tiny_assets, poses):
    pose, index, scale = poses
    clouds = ObjectClouds(tiny_assets)
    searched = surface_terms(hand, clouds, (SURFACE_DISTANCE_TERM,))
    kept = surface_terms(hand, clouds, (SURFACE_DISTANCE_TERM,), training_grasps=len(pose) + 5)
    rows = torch.arange(len(pose)) + 3  # the training grasps' rows: any, as long as each names one grasp
    target = _parts(pose)
    for offset in (0.004, -0.006):  # the second call reads what the first kept
        moved = _moved(pose, scale, offset)
        values = []
        for terms, extra in ((searched, {}), (kept, {"grasp_index": rows})):
            decoded = moved.clone().requires_grad_(True)
            value = terms(*_parts(decoded), index, scale, target, **extra)[SURFACE_DISTANCE_TERM]
            value.sum().backward()
            values.append((value.detach(), decoded.grad))
        assert torch.equal(values[0][0], values[1][0]) and torch.equal(values[0][1], values[1][1])
        assert (values[0][0] > 0).all()


def test_training_with_kept_nearest_samples_is_the_same_training(hand, tiny_assets, make_grasps, small_model_config):
    grasps = make_grasps(hand, 8, seed=1)
    data = build_training_data(grasps, tiny_assets, hand)
    config = TrainConfig(model=small_model_config, epochs=3, max_steps=0, batch_size=8, clouds_per_batch=2, points_per_cloud=64,
                         learning_rate=3e-3, validation_fraction=0.0, energy_warmup_fraction=0.0, weight_surface_distance=1.0)
    histories = []
    for training_grasps in (0, len(data.pose_features)):
        surface = surface_terms(hand, data.clouds, config.surface_terms(), training_grasps=training_grasps)
        terms = with_surface_terms(unbuilt_energy_terms, surface, mesh=False)
        histories.append(train_cvae(data, np.arange(len(grasps)), np.zeros(0, np.int64), config, terms, seed=0).history)
    differing = {key for a, b in zip(*histories) for key in a if a[key] != b[key] and not (np.isnan(a[key]) and np.isnan(b[key]))}
    assert differing <= {"seconds"}, differing
