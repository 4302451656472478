"""Optimization from scratch in groups of objects (``optimize_grasps.objects_per_energy``): memory per group, same grasps."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from dexlite_pipeline.energy.config import EnergyConfig
from dexlite_pipeline.optim.from_scratch import synthesize

from power_baseline import power_settings

ARRAYS = ("hand_pose", "init_pose", "contact_index", "E_total", "stopped_at_iteration", "object_id", "scale", "grasp_type")


@pytest.fixture(scope="module")
def two_objects(optim_objects):
    from dexlite_pipeline.objects.assets import load_asset

    return [load_asset(optim_objects, "sphere"), load_asset(optim_objects, "box")]


def _run(assets, objects_per_energy: int, keyed_seed: int | None):
    settings = dataclasses.replace(power_settings(), objects_per_energy=objects_per_energy, annealing=dataclasses.replace(
        power_settings().annealing, iterations=20))
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        grasps, stats = synthesize(assets, settings, EnergyConfig(object_point_spacing_m=0.004), torch.Generator().manual_seed(5),
                                   keyed_seed=keyed_seed)
    finally:
        torch.set_num_threads(threads)
    return grasps, stats


def _same(a, b) -> None:
    for name in ARRAYS:
        assert np.array_equal(a.arrays[name], b.arrays[name]), name


def test_keyed_runs_are_the_same_in_groups_of_one_object_and_each_group_builds_its_own_energy(two_objects, monkeypatch):
    """``dexlite grasp``'s keyed draws: one energy per object gives every array of one energy for both, and each energy
    is built of its group's objects only."""
    from dexlite_pipeline.energy.grasp_energy import GraspEnergy

    together, stats_together = _run(two_objects, 0, keyed_seed=7)
    built = []
    original = GraspEnergy.from_assets.__func__

    def recording(cls, hand, assets, *args, **kwargs):
        built.append([a.object_id for a in assets])
        return original(cls, hand, assets, *args, **kwargs)

    monkeypatch.setattr(GraspEnergy, "from_assets", classmethod(recording))
    grouped, stats_grouped = _run(two_objects, 1, keyed_seed=7)
    assert built == [["sphere"], ["box"]]
    _same(together, grouped)
    assert together.arrays["object_id"].tolist() == ["sphere"] * 6 + ["box"] * 6
    assert {k: stats_grouped[k] for k in ("grasps", "passing", "stopped_early")} == \
        {k: stats_together[k] for k in ("grasps", "passing", "stopped_early")}


def test_a_shard_of_no_more_objects_than_a_group_is_optimized_as_before(two_objects):
    """Draws in batch order (the optimize_grasps stage): a group of at least the shard's objects is the one energy's run;
    smaller groups still give every object its grasps, in object order."""
    together, _ = _run(two_objects, 0, keyed_seed=None)
    _same(together, _run(two_objects, 2, keyed_seed=None)[0])
    grouped, stats = _run(two_objects, 1, keyed_seed=None)
    assert grouped.arrays["object_id"].tolist() == together.arrays["object_id"].tolist()
    assert stats["grasps"] == 12 and np.isfinite(grouped.arrays["E_total"]).all()
