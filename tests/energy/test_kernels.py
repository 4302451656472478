"""The compiled CPU passes of the energy (``energy.*_kernel``) against the torch operations they replace."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dexlite_pipeline.energy.config import EnergyConfig
from dexlite_pipeline.energy.grasp_energy import GraspEnergy
from dexlite_pipeline.hand.model import HandFrames
from dexlite_pipeline.objects.assets import load_asset

SCALES = (0.07, 0.08, 0.1)


@pytest.fixture(scope="module")
def energy(hand, sphere_objects):
    assets = [load_asset(sphere_objects, "sphere"), load_asset(sphere_objects, "box")]
    return GraspEnergy.from_assets(hand, assets, EnergyConfig(object_point_spacing_m=0.002), max_scale=max(SCALES))


def _poses(count: int, seed: int) -> torch.Tensor:
    """Hands around the objects' centres, palm 2–8 cm away, fingers from open to curled into each other."""
    g = torch.Generator().manual_seed(seed)
    pose = torch.zeros(count, 28)
    pose[:, :3] = torch.nn.functional.normalize(torch.randn(count, 3, generator=g), dim=1) * (0.02 + 0.06 * torch.rand(count, 1, generator=g))
    pose[:, 3:6] = torch.pi * (2 * torch.rand(count, 3, generator=g) - 1)
    pose[:, 6:] = 1.4 * torch.rand(count, 22, generator=g)
    return pose


def _evaluate(term, hand, pose, object_index, scale, use_torch: bool):
    frames = hand.forward(pose)
    rotation = frames.rotation.detach().clone().requires_grad_(True)
    translation = frames.translation.detach().clone().requires_grad_(True)
    call = term.evaluate_with_torch if use_torch else term
    result = call(HandFrames(rotation, translation), object_index, scale)
    grad_rotation, grad_translation = torch.autograd.grad(result.energy.sum(), (rotation, translation), allow_unused=True)
    zeros = torch.zeros_like
    return (
        result.energy.detach(),
        result.object_in_hand_max_m,
        result.hand_in_object_max_m,
        zeros(rotation) if grad_rotation is None else grad_rotation,
        zeros(translation) if grad_translation is None else grad_translation,
    )


def test_kernel_equals_the_torch_operations(hand, energy):
    """Energy, both depths and the gradient in every link frame agree (two objects, three scales, deep and curled hands)."""
    count = 96
    pose = _poses(count, seed=11)
    object_index = torch.arange(count) % 2
    scale = torch.tensor(SCALES)[torch.arange(count) % 3]
    kernel = _evaluate(energy.penetration, hand, pose, object_index, scale, use_torch=False)
    reference = _evaluate(energy.penetration, hand, pose, object_index, scale, use_torch=True)
    assert (reference[0] > 1e-4).sum() >= count // 3, "the poses should penetrate"
    assert (reference[2] > 0.01).sum() >= 5, "some links buried deep"
    for name, got, want in zip(("energy", "object in hand", "hand in object", "d/d rotation", "d/d translation"), kernel, reference):
        tolerance = 1e-5 * float(want.abs().max()) + 1e-7
        assert torch.allclose(got, want, rtol=1e-4, atol=tolerance), name


def test_hit_buffers_grow_without_changing_the_result(hand, energy):
    """Grasps with more object points inside the hand than the buffers hold are evaluated again with longer ones."""
    count = 12
    pose = _poses(count, seed=15)
    object_index = torch.arange(count) % 2
    scale = torch.tensor(SCALES)[torch.arange(count) % 3]
    kernel = energy.penetration.kernel
    default = _evaluate(energy.penetration, hand, pose, object_index, scale, use_torch=False)
    kernel.initial_hits = 2
    try:
        small = _evaluate(energy.penetration, hand, pose, object_index, scale, use_torch=False)
    finally:
        kernel.initial_hits = type(kernel).initial_hits
    assert (default[1] > 0).sum() >= 4, "some grasps must have object points inside the hand"
    for got, want in zip(small, default):
        assert torch.equal(got, want)


def test_a_grasp_is_evaluated_the_same_alone_and_in_a_batch(hand, energy):
    """Bit for bit: the kernel computes each grasp on its own (the frames are the batch's, sliced)."""
    count = 24
    frames = hand.forward(_poses(count, seed=12))
    object_index = torch.arange(count) % 2
    scale = torch.tensor(SCALES)[torch.arange(count) % 3]

    def evaluate(rows):
        rotation = frames.rotation.detach()[rows].clone().requires_grad_(True)
        translation = frames.translation.detach()[rows].clone().requires_grad_(True)
        result = energy.penetration(HandFrames(rotation, translation), object_index[rows], scale[rows])
        gradient = torch.autograd.grad(result.energy.sum(), (rotation, translation))
        return (result.energy.detach(), result.object_in_hand_max_m, result.hand_in_object_max_m, *gradient)

    batch = evaluate(torch.arange(count))
    assert (batch[0] > 0).sum() >= 6
    for row in (0, 7, 23):
        for got, want in zip(evaluate(torch.tensor([row])), batch):
            assert torch.equal(got[0], want[row])


def test_without_gradient_nothing_is_attached(hand, energy):
    pose = _poses(8, seed=13)
    with torch.no_grad():
        result = energy.penetration(hand.forward(pose), torch.zeros(8, dtype=torch.long), torch.full((8,), 0.08))
    assert not result.energy.requires_grad and result.energy.shape == (8,)


def test_grid_distance_and_gradient_equal_the_bank(hand, energy):
    """The kernel's grid lookup at points inside, near and outside the grid box equals SdfBank's, gradient included."""
    from dexlite_pipeline.energy.grid_kernel import grid_distance

    g = torch.Generator().manual_seed(14)
    points = (torch.rand(200, 3, generator=g) * 2 - 1) * 0.15  # metres; the objects reach 0.08-0.1, the grids a little beyond
    index = torch.arange(200) % 2
    scale = torch.full((200,), 0.08)
    x = points.clone().requires_grad_(True)
    distance, _ = energy.bank.signed_distance(x, index, scale, with_normal=False)
    (gradient,) = torch.autograd.grad(distance.sum(), x)
    arrays = energy.penetration.kernel.static
    volumes, grid_min, voxel_size = arrays.volumes, arrays.grid_min, arrays.voxel_size
    out = np.empty(3)
    for i in range(200):
        o = int(index[i])
        p = points[i].double().numpy() / 0.08
        value = grid_distance(volumes, o, volumes.shape[1], grid_min, voxel_size[o], p[0], p[1], p[2], out) * 0.08
        assert value == pytest.approx(float(distance[i].detach()), abs=2e-6)
        assert np.allclose(out, gradient[i].double().numpy(), rtol=1e-4, atol=1e-4)


def test_self_penetration_kernel_equals_the_torch_operations(hand, energy):
    """E_spen and its gradient in every link frame, curled fingers (many close pairs) and open hands."""
    pose = _poses(48, seed=16)
    frames = hand.forward(pose)
    results = []
    for call in (energy.self_penetration, energy.self_penetration.evaluate_with_torch):
        rotation = frames.rotation.detach().clone().requires_grad_(True)
        translation = frames.translation.detach().clone().requires_grad_(True)
        value = call(HandFrames(rotation, translation))
        results.append((value.detach(), *torch.autograd.grad(value.sum(), (rotation, translation))))
    assert (results[1][0] > 0).sum() >= 10, "the poses should press fingers together"
    for name, got, want in zip(("E_spen", "d/d rotation", "d/d translation"), *results):
        assert torch.allclose(got, want, rtol=1e-4, atol=1e-5 * float(want.abs().max())), name


def test_contact_kernel_equals_the_bank(hand, energy, sphere_objects):
    """Points, distances and normals of chosen contacts, and the gradient of a loss of all three in the frames,
    equal ``SdfBank.signed_distance``'s (pads inside, on and off the objects, some beyond the grid box). The
    reference runs in float64 like the kernel: just outside the grid box the normal's Jacobian divides by the
    distance to the box, and float32 rounding there is not a difference worth testing."""
    from dexlite_pipeline.objects.assets import SdfBank

    count = 64
    pose = _poses(count, seed=17)
    pose[::8, :3] *= 6.0  # hands far out: contacts outside the grid box
    frames = hand.forward(pose)
    object_index = torch.arange(count) % 2
    scale = torch.tensor(SCALES)[torch.arange(count) % 3]
    contacts = torch.randint(0, len(hand.all_contact_link), (count, 4), generator=torch.Generator().manual_seed(18))  # pads and side candidates
    weights = [torch.randn(shape, generator=torch.Generator().manual_seed(19 + i), dtype=torch.float64)
               for i, shape in enumerate(((count, 4, 3), (count, 4), (count, 4, 3)))]
    bank64 = SdfBank([load_asset(sphere_objects, "sphere"), load_asset(sphere_objects, "box")], dtype=torch.float64)
    bank64.grid_min, bank64.voxel_size = energy.bank.grid_min.double(), energy.bank.voxel_size.double()  # the kernel's (float32) values
    results = []
    for use_kernel in (True, False):
        rotation = frames.rotation.detach().double().clone().requires_grad_(True)
        translation = frames.translation.detach().double().clone().requires_grad_(True)
        moved = HandFrames(rotation, translation)
        if use_kernel:
            points, distance, normal = energy.contact_kernel(moved, contacts, object_index, scale)
        else:
            points = moved.transform(hand.all_contact_points_local.double(), hand.all_contact_link)
            points = torch.gather(points, 1, contacts[..., None].expand(-1, -1, 3))
            distance, normal = bank64.signed_distance(points, object_index[:, None], scale.double()[:, None])
        loss = sum((value * weight).sum() for value, weight in zip((points, distance, normal), weights))
        results.append((points.detach(), distance.detach(), normal.detach(), *torch.autograd.grad(loss, (rotation, translation))))
    assert (results[1][1] > 0).sum() >= 8 and (results[1][1] < -0.05).sum() >= 8, "contacts inside and far outside"
    for name, got, want in zip(("points", "distance", "normal", "d/d rotation", "d/d translation"), *results):
        assert torch.allclose(got, want, rtol=1e-4, atol=1e-6 * float(want.abs().max())), name


def test_table_kernel_equals_the_torch_operations(hand):
    """E_table and its gradient in every link frame on tilted tables cutting through the hand."""
    from dexlite_pipeline.energy.terms import TableTerm

    count = 48
    frames = hand.forward(_poses(count, seed=21))
    g = torch.Generator().manual_seed(22)
    normal = torch.nn.functional.normalize(torch.tensor([0.0, 0.0, 1.0]) + 0.4 * torch.randn(count, 3, generator=g), dim=1)
    offset = 0.06 * torch.randn(count, generator=g)
    term = TableTerm(hand)
    results = []
    for call in (term, term.evaluate_with_torch):
        rotation = frames.rotation.detach().clone().requires_grad_(True)
        translation = frames.translation.detach().clone().requires_grad_(True)
        value = call(HandFrames(rotation, translation), normal, offset)
        results.append((value.detach(), *torch.autograd.grad(value.sum(), (rotation, translation))))
    assert (results[1][0] > 0).sum() >= 10 and (results[1][0] == 0).sum() >= 5, "hands through and above their tables"
    for name, got, want in zip(("E_table", "d/d rotation", "d/d translation"), *results):
        assert torch.allclose(got, want, rtol=1e-4, atol=1e-5 * float(want.abs().max())), name
