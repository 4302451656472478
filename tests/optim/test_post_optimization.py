"""Post-optimization lowers E_post on perturbed grasp-like poses and keeps the raw pose beside the refined one."""

import dataclasses

import numpy as np
import pytest
import torch

from dexlite_pipeline.energy.config import EnergyConfig
from dexlite_pipeline.energy.grasp_energy import GraspEnergy
from dexlite_pipeline.optim.config import AnnealingSchedule, PostOptimizeConfig
from dexlite_pipeline.optim.post import refine

pytestmark = pytest.mark.usefixtures("one_torch_thread")  # small tensors on a shared machine


def test_post_optimization_lowers_e_post(hand, tiny_assets, make_grasps):
    grasps = make_grasps(hand, 12, seed=4)
    rng = np.random.default_rng(0)
    pose = grasps.hand_pose.copy()
    pose[:, :3] += rng.normal(scale=0.005, size=(12, 3))
    pose[:, 6:] += rng.normal(scale=0.1, size=(12, 22))
    config = PostOptimizeConfig(annealing=AnnealingSchedule(iterations=80), batch_size=8)  # two optimizer batches
    energy = GraspEnergy.from_assets(hand, tiny_assets, EnergyConfig(weights=config.energy_weights, object_point_spacing_m=0.005))
    refined = refine(
        energy, torch.as_tensor(pose, dtype=torch.float32), energy.object_index(grasps.object_id),
        torch.as_tensor(grasps.scale), config, torch.Generator().manual_seed(0),
    )
    a = refined.arrays
    assert a["hand_pose"].shape == a["raw_hand_pose"].shape == (12, 28)
    assert np.allclose(a["raw_hand_pose"], pose, atol=1e-6)
    assert a["energy_trace"].shape == (12, 81) and list(refined.trace_iterations) == list(range(81))
    assert np.allclose(a["energy_trace"][:, -1], a["E_post"], rtol=1e-5)
    for name in ("E_fc", "E_dis", "E_pen"):
        assert a[f"trace_{name}"].shape == (12, 81)
        assert np.allclose(a[f"trace_{name}"][:, -1], a[name], rtol=1e-5)
    assert np.median(a["E_post"]) < 0.8 * np.median(a["raw_E_post"])
    assert (a["E_post"] < a["raw_E_post"]).mean() >= 0.75
    recomputed = energy(torch.as_tensor(a["hand_pose"]), object_index=energy.object_index(grasps.object_id),
                        scale=torch.as_tensor(grasps.scale), contact_index=torch.as_tensor(a["contact_index"]).long())
    assert np.allclose(recomputed.total.detach().numpy(), a["E_post"], rtol=1e-3, atol=1e-3)


def test_post_optimization_config_maps_to_the_optimizer():
    config = PostOptimizeConfig()
    annealing = config.optimizer_config()
    assert (annealing.iterations, annealing.step_size, annealing.rmsprop_mu) == (200, 0.005, 0.98)
    assert (annealing.starting_temperature, annealing.temperature_decay, annealing.temperature_period) == (18.0, 0.95, 30)
    assert annealing.contact_switch_probability == 0.5
    assert dataclasses.astuple(config.energy_weights) == (1.0, 100.0, 100.0, 10.0, 1.0, 100.0)  # E_table last (tabletop mode only)
    # sampled (learned) starts stop where hopeless; random starts (the baseline) run every iteration
    assert config.optimizer_config(learned_start=True).stop_hopeless == config.stop_hopeless and config.stop_hopeless.iterations
    assert annealing.stop_hopeless.iterations == ()
