"""E_table (tabletop mode): exact lowest points of the hand's shapes, zero above the table, the weighted total."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dexlite_pipeline.energy.grasp_energy import GraspEnergy
from dexlite_pipeline.energy.table_clearance import HandTableClearance
from dexlite_pipeline.energy.terms import TableTerm
from dexlite_pipeline.objects.assets import load_asset
from dexlite_pipeline.objects.rest_pose import SupportPlane
from dexlite_pipeline.tabletop import SupportPlanes

SCALE = 0.08


def _random_poses(count: int, seed: int) -> torch.Tensor:
    generator = torch.Generator().manual_seed(seed)
    pose = torch.zeros(count, 28)
    pose[:, :3] = 0.1 * torch.randn(count, 3, generator=generator)
    pose[:, 3:6] = torch.rand(count, 3, generator=generator) * 6.3 - 3.15
    pose[:, 6:] = torch.rand(count, 22, generator=generator) * 0.8
    return pose


def _unit_normals(count: int, seed: int) -> torch.Tensor:
    normal = torch.randn(count, 3, generator=torch.Generator().manual_seed(seed))
    return normal / normal.norm(dim=1, keepdim=True)


def test_lowest_shape_points_are_exact_against_dense_surface_samples(hand):
    """The support-function lowest point of every shape lies at or below all of its dense surface
    samples and within a millimetre of the lowest one (boxes: the samples approach the corners as they get denser)."""
    from dexlite_pipeline.hand.model import _shape_surface_samples

    pose, normal = _random_poses(4, 0), _unit_normals(4, 1)
    frames = hand.forward(pose)
    lowest = HandTableClearance(hand).lowest_heights(frames, normal, torch.zeros(4))  # (B, S)
    for s in range(len(hand.shape_kind)):
        local = torch.as_tensor(_shape_surface_samples(int(hand.shape_kind[s]), hand.shape_size[s].tolist(), 30000), dtype=hand.dtype)
        in_link = local @ hand.shape_rot[s].T + hand.shape_pos[s]
        link = int(hand.shape_link[s])
        world = in_link @ frames.rotation[:, link].transpose(1, 2) + frames.translation[:, link, None]  # (B, P, 3)
        low = (world * normal[:, None]).sum(-1).min(dim=1).values
        assert (lowest[:, s] <= low + 1e-6).all()
        assert (lowest[:, s] > low - 0.001).all()


def test_table_term_is_zero_above_and_grows_with_depth_below(hand):
    term = TableTerm(hand)
    pose = _random_poses(1, 3)
    frames = hand.forward(pose)
    up = torch.tensor([[0.0, 0.0, 1.0]])
    lowest = float(HandTableClearance(hand).lowest_heights(frames, up, torch.zeros(1)).min())
    # Table just below the hand's lowest point: zero; raised through it by 1 and 5 mm: positive, growing.
    assert float(term(frames, up, torch.tensor([-lowest + 1e-4]))) == 0.0
    one, five = (float(term(frames, up, torch.tensor([-lowest + d]))) for d in (-0.001, -0.005))
    assert one >= 0.001 - 1e-7 and five > one


def test_gradient_moves_the_hand_up(hand):
    """The gradient of E_table with respect to the palm position points down the normal (descent lifts the hand)."""
    pose = _random_poses(4, 5).requires_grad_(True)
    normal = _unit_normals(4, 6)
    frames = hand.forward(pose)
    lowest = HandTableClearance(hand).lowest_heights(frames, normal, torch.zeros(4)).detach().min(dim=1).values
    energy = TableTerm(hand)(frames, normal, -lowest - 0.01).sum()  # the table 1 cm above each hand's lowest point
    (grad,) = torch.autograd.grad(energy, pose)
    along = (grad[:, :3] * normal).sum(1)
    assert (along < 0).all()


@pytest.fixture(scope="module")
def assets(sphere_objects):
    return [load_asset(sphere_objects, "sphere"), load_asset(sphere_objects, "box")]


def test_floating_energy_has_the_five_terms_and_tabletop_adds_weighted_e_table(hand, assets):
    planes = SupportPlanes({"sphere": SupportPlane((0.0, 0.0, 1.0), 1.0), "box": SupportPlane((0.0, 0.0, 1.0), 0.3)})
    floating = GraspEnergy.from_assets(hand, assets)
    tabletop = GraspEnergy.from_assets(hand, assets, support_planes=planes)
    pose = _random_poses(6, 7)
    pose[:, 2] -= 0.05  # some hands reach below the sphere's base
    index, scale = torch.tensor([0, 0, 0, 1, 1, 1]), torch.full((6,), SCALE)
    base = floating(pose, object_index=index, scale=scale)
    table = tabletop(pose, object_index=index, scale=scale, contact_index=base.contact_index)
    assert "E_table" not in base.terms and set(table.terms) == {*base.terms, "E_table"}
    for name, value in base.terms.items():
        assert torch.equal(table.terms[name], value)
    assert (table.terms["E_table"] > 0).any()
    expected = base.total + tabletop.weights.table * table.terms["E_table"]
    assert torch.allclose(table.total, expected, rtol=1e-6)
    # The offset is per unit scale: the sphere's table (offset 1, radius 1) is at z = -scale.
    normal, offset = tabletop.support(index, scale)
    np.testing.assert_allclose(offset.numpy(), [SCALE] * 3 + [0.3 * SCALE] * 3, rtol=1e-6)
