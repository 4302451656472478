"""Contact slots (a grasp type's contact template): draws and contact searches stay within each contact's slot."""

from __future__ import annotations

import pytest
import torch

from dexlite_pipeline.energy.config import EnergyConfig
from dexlite_pipeline.energy.contact_slots import ContactSlots
from dexlite_pipeline.energy.grasp_energy import GraspEnergy
from dexlite_pipeline.objects.assets import load_asset
from dexlite_pipeline.optim.grasp_random import GraspRandom

# Two templates: every contact any of candidates 0-2; and contacts 0-1 on {130, 131}, 2-3 on the side candidates {140, 145}.
TEMPLATES = [((0, 1, 2),) * 4, ((130, 131), (130, 131), (140, 145), (140, 145))]


@pytest.fixture(scope="module")
def energy(hand, sphere_objects):
    return GraspEnergy.from_assets(hand, [load_asset(sphere_objects, "sphere")], EnergyConfig(object_point_spacing_m=0.004), max_scale=0.1)


def _poses(count: int) -> torch.Tensor:
    g = torch.Generator().manual_seed(3)
    pose = torch.zeros(count, 28)
    pose[:, :3] = torch.nn.functional.normalize(torch.randn(count, 3, generator=g), dim=1) * 0.06
    pose[:, 3:6] = torch.pi * (2 * torch.rand(count, 3, generator=g) - 1)
    pose[:, 6:] = 0.8 * torch.rand(count, 22, generator=g)
    return pose


def test_draw_maps_uniforms_into_each_slot():
    slots = ContactSlots.from_templates(TEMPLATES, torch.tensor([0, 1, 1]))
    uniform = torch.tensor([[0.0, 0.34, 0.67, 0.999], [0.0, 0.6, 0.2, 0.9], [0.49, 0.5, 0.5, 0.49]], dtype=torch.float64)
    assert slots.draw(uniform).tolist() == [[0, 1, 2, 2], [130, 131, 140, 145], [130, 131, 145, 140]]
    assert slots.candidate_count == 146
    masks = slots.masks(146)
    assert masks.shape == (3, 4, 146) and masks[1, 2].nonzero().flatten().tolist() == [140, 145]
    assert slots.take(torch.tensor([0])).draw(uniform[:1]).tolist() == [[0, 1, 2, 2]]


@pytest.mark.parametrize("keyed", [False, True])
def test_contact_search_only_picks_allowed_candidates(energy, keyed):
    count = 24
    pose = _poses(count)
    kind = torch.arange(count) % 2
    slots = ContactSlots.from_templates(TEMPLATES, kind)
    start = slots.draw(torch.zeros(count, 4, dtype=torch.float64))
    draw = None
    if keyed:
        random = GraspRandom(7, torch.arange(count))
        draw = lambda weight, n: random.weighted(weight, 1, GraspRandom.CONTACT_SEARCH, n)  # noqa: E731
    object_index, scale = torch.zeros(count, dtype=torch.long), torch.full((count,), 0.08)
    chosen = energy.best_contacts(pose, object_index, scale, start, 32, torch.Generator().manual_seed(0), draw=draw, slots=slots)
    allowed = slots.masks(slots.candidate_count)
    assert bool(torch.gather(allowed, 2, chosen[..., None]).all())
    assert not torch.equal(chosen, start)  # the search moved some contacts
    before = energy(pose, object_index=object_index, scale=scale, contact_index=start).total
    after = energy(pose, object_index=object_index, scale=scale, contact_index=chosen).total
    assert bool((after <= before + 1e-5).all())  # never worse


def test_weighted_draws_per_slot_follow_each_slot_weights():
    random = GraspRandom(1, torch.arange(2))
    weight = torch.zeros(2, 3, 5, dtype=torch.float64)
    weight[:, 0, 1] = 1.0
    weight[:, 1, 3:] = 1.0
    weight[:, 2] = 1.0
    drawn = random.weighted(weight, 0, GraspRandom.CONTACT_SEARCH, 200)
    assert drawn.shape == (2, 3, 200)
    assert set(drawn[:, 0].flatten().tolist()) == {1}
    assert set(drawn[:, 1].flatten().tolist()) == {3, 4}
    assert set(drawn[:, 2].flatten().tolist()) == {0, 1, 2, 3, 4}
    flat = random.weighted(weight[:, 2], 0, GraspRandom.CONTACT_SEARCH, 200)  # two-dimensional weights as before
    assert flat.shape == (2, 200)
