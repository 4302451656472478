"""The surface-sample penetration loss term: which samples it finds inside the hand, how it grows with depth, its
gradient, and a training run with it and no mesh energy."""

import dataclasses

import numpy as np
import pytest
import torch

from dexlite_pipeline.energy.config import EnergyConfig
from dexlite_pipeline.energy.grasp_energy import GraspEnergy
from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix
from dexlite_pipeline.model.config import SURFACE_PENETRATION_TERM, TrainConfig
from dexlite_pipeline.model.data import ObjectClouds, build_training_data
from dexlite_pipeline.model.surface_penetration import samples_inside_hand, surface_penetration_terms
from dexlite_pipeline.model.trainer import unbuilt_energy_terms, uses_energies
from dexlite_pipeline.model.training import train_cvae, with_surface_penetration


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


def _term(hand, tiny_assets, pose, index, scale):
    term = surface_penetration_terms(hand, ObjectClouds(tiny_assets))
    return term(euler_xyz_to_matrix(pose[:, 3:6]), pose[:, :3], pose[:, 6:], index, scale)


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


def test_training_with_it_builds_no_mesh_energy_and_logs_it(hand, tiny_assets, make_grasps, small_model_config):
    grasps = make_grasps(hand, 8, seed=1)
    data = build_training_data(grasps, tiny_assets, hand)
    config = TrainConfig(model=small_model_config, epochs=20, max_steps=0, batch_size=8, clouds_per_batch=2, points_per_cloud=64,
                         learning_rate=3e-3, validation_fraction=0.0, energy_warmup_fraction=0.0, weight_surface_penetration=10.0)
    assert not uses_energies(config, table=True) and SURFACE_PENETRATION_TERM in config.weights()
    assert SURFACE_PENETRATION_TERM not in dataclasses.replace(config, weight_surface_penetration=0.0).weights()
    terms = with_surface_penetration(unbuilt_energy_terms, surface_penetration_terms(hand, data.clouds), mesh=False)
    result = train_cvae(data, np.arange(len(grasps)), np.zeros(0, np.int64), config, terms, seed=0)
    first, last = result.history[0], result.history[-1]
    assert np.isfinite(last[f"train_{SURFACE_PENETRATION_TERM}"]) and all(np.isnan(last[f"train_{k}"]) for k in ("fc", "pen"))
    assert last[f"train_{SURFACE_PENETRATION_TERM}"] < first[f"train_{SURFACE_PENETRATION_TERM}"]
