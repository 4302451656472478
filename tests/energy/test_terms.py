"""Each energy term against hand-computed values on simple cases, plus exactness of the culling."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import torch

from dexlite_pipeline.energy.config import EnergyConfig
from dexlite_pipeline.energy.grasp_energy import GraspEnergy, combined_energy
from dexlite_pipeline.energy.per_grasp import evaluate_grasp_energies
from dexlite_pipeline.energy.terms import (
    ContactDistanceTerm,
    ForceClosureTerm,
    JointLimitTerm,
    SelfPenetrationTerm,
)
from dexlite_pipeline.hand.model import CAPSULE, shape_signed_distance
from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.objects.assets import load_asset

SCALE = 0.08  # sphere radius in metres


@pytest.fixture(scope="module")
def sphere_energy(hand, sphere_objects):
    return GraspEnergy.from_assets(hand, [load_asset(sphere_objects, "sphere"), load_asset(sphere_objects, "box")], max_scale=SCALE)


def _sphere_sdf(energy, points):
    points = torch.as_tensor(points, dtype=torch.float32)[None]
    index = torch.zeros(1, 1, dtype=torch.long)
    return energy.bank.signed_distance(points, index, torch.full((1, 1), SCALE))


def test_force_closure_two_opposite_contacts_on_sphere_is_zero(sphere_energy):
    points = [[SCALE, 0, 0], [-SCALE, 0, 0], [0, SCALE, 0], [0, -SCALE, 0]]
    _, normal = _sphere_sdf(sphere_energy, points)
    assert torch.allclose(normal[0, 0], torch.tensor([1.0, 0, 0]), atol=0.02)
    e_fc = ForceClosureTerm()(torch.tensor([points], dtype=torch.float32), normal)
    assert e_fc.item() < 1e-3


def test_force_closure_one_sided_contacts_is_not_zero(sphere_energy):
    # All four contacts on the same side: normals add up to ~4 (force ‖Σn‖² ≈ 16 minus spread).
    points = [[SCALE, 0, 0], [SCALE * math.cos(0.2), SCALE * math.sin(0.2), 0], [SCALE, 0, 0], [SCALE, 0, 0]]
    _, normal = _sphere_sdf(sphere_energy, points)
    e_fc = ForceClosureTerm()(torch.tensor([points], dtype=torch.float32), normal)
    expected = (normal[0].sum(0) ** 2).sum()  # torque of radial normals is zero on a sphere
    assert e_fc.item() == pytest.approx(expected.item(), rel=1e-3)
    assert e_fc.item() > 15.0


def test_force_closure_exact_formula():
    x = torch.tensor([[[0.0, 0.1, 0.0], [0.0, -0.1, 0.0]]])
    n = torch.tensor([[[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]])
    # Σn = (2, 0, 0); Σ x×n = (0,0,-0.1) + (0,0,0.1) = 0.
    assert ForceClosureTerm()(x, n).item() == pytest.approx(4.0)
    n = torch.tensor([[[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]])
    # Σn = 0; torques (0,0,-0.1) and (0,0,-0.1): ‖(0,0,-0.2)‖² = 0.04 (a couple).
    assert ForceClosureTerm()(x, n).item() == pytest.approx(0.04)


def test_contact_distance_of_points_at_known_distance(sphere_energy):
    offsets = [0.01, 0.02, -0.005, 0.0]  # outside, outside, inside, on the surface
    points = [[(SCALE + o), 0, 0] for o in offsets]
    distance, _ = _sphere_sdf(sphere_energy, points)
    assert distance[0].tolist() == pytest.approx([-0.01, -0.02, 0.005, 0.0], abs=1e-3)
    e_dis = ContactDistanceTerm()(distance)
    assert e_dis.item() == pytest.approx(0.035, abs=2e-3)


def test_capsule_and_box_signed_distance():
    size = torch.tensor([0.01, 0.02, 0.0])
    kind = torch.tensor(CAPSULE)
    points = torch.tensor([[0.003, 0.0, 0.0], [0.0, 0.0, 0.025], [0.0, 0.02, 0.0]])
    sd = shape_signed_distance(points, kind, size)
    # inside by r − 0.003; on the cap axis 0.005 past the segment end; outside by 0.01.
    assert sd.tolist() == pytest.approx([0.007, 0.005, -0.01], abs=1e-6)
    box = shape_signed_distance(torch.tensor([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0]]), torch.tensor(1), torch.tensor([0.02, 0.01, 0.03]))
    assert box.tolist() == pytest.approx([0.01, -0.03], abs=1e-6)


def _dense_self_penetration(keypoints: torch.Tensor, pairs: tuple[torch.Tensor, torch.Tensor], margin_m: float) -> torch.Tensor:
    """Reference E_spen: every listed pair (i, j) of keypoints (B, K, 3), no culling."""
    return SelfPenetrationTerm.pair_penalty(keypoints[:, pairs[0]], keypoints[:, pairs[1]], margin_m).sum(dim=-1)


def test_self_penetration_of_two_keypoints_one_cm_apart():
    keypoints = torch.tensor([[[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.5, 0.0, 0.0]]])
    pairs = (torch.tensor([0, 0, 1]), torch.tensor([1, 2, 2]))
    e_spen = _dense_self_penetration(keypoints, pairs, 0.02)
    assert e_spen.item() == pytest.approx(0.01, abs=1e-6)


def test_joint_limit_violation(hand):
    term = JointLimitTerm(hand.joint_limits)
    q = hand.joint_limits.mean(dim=1).clone()[None]
    assert term(q).item() == 0.0
    q[0, 1] = hand.joint_limits[1, 1] + 0.1  # FFJ2 0.1 over its upper limit
    q[0, 17] = hand.joint_limits[17, 0] - 0.2  # THJ4 0.2 under its lower limit
    assert term(q).item() == pytest.approx(0.3, abs=1e-6)


def _poses_near_sphere(count: int, seed: int) -> torch.Tensor:
    """Open hands with the palm 4–9 cm from the sphere's centre, facing it (some penetrate)."""
    from dexlite_pipeline.hand.rotation import matrix_to_euler_xyz
    from dexlite_pipeline.optim.init import PALM_APPROACH

    g = torch.Generator().manual_seed(seed)
    direction = torch.nn.functional.normalize(torch.randn(count, 3, generator=g), dim=1)
    hand_a = torch.tensor(PALM_APPROACH)
    hand_b = torch.tensor([1.0, 0.0, 0.0])
    side = torch.nn.functional.normalize(torch.linalg.cross(direction, torch.randn(count, 3, generator=g)), dim=1)
    world = torch.stack([-direction, side, torch.linalg.cross(-direction, side)], dim=2)
    local = torch.stack([hand_a, hand_b, torch.linalg.cross(hand_a, hand_b)], dim=1)
    rotation = world @ local.T
    distance = 0.04 + 0.05 * torch.rand(count, 1, generator=g)
    joints = 0.3 * torch.rand(count, 22, generator=g)
    return torch.cat([direction * distance, matrix_to_euler_xyz(rotation), joints], dim=1)


def _used_object_depths(energy, hand, frames, index, scale):
    """(B, P) depth of each of the grasp's own object points in the hand (0 for points past its count) and their weights (B,)."""
    count, weight = energy.penetration.point_counts(index, scale)
    points = energy.penetration.object_points[index, : int(count.max())] * scale[:, None, None]
    depth = hand.collision_signed_distance(frames, points).clamp(min=0)
    used = torch.arange(points.shape[1])[None, :] < count[:, None]
    return depth * used, weight


def test_penetration_culling_is_exact(hand, sphere_energy):
    """Culled E_pen equals the brute force: all object points in the hand plus all buried sphere centres."""
    pose = _poses_near_sphere(24, seed=1)
    index = torch.zeros(24, dtype=torch.long)
    scale = torch.full((24,), SCALE)
    frames = hand.forward(pose)
    result = sphere_energy.penetration(frames, index, scale)

    object_in_hand, weight = _used_object_depths(sphere_energy, hand, frames, index, scale)
    spheres = sphere_energy.penetration.spheres
    centre = sphere_energy.penetration.sphere_map(frames)
    distance, _ = sphere_energy.bank.signed_distance(centre, index[:, None], scale[:, None])
    hand_in_object = (distance + spheres.radius).clamp(min=0)
    brute = object_in_hand.sum(1) * weight + distance.clamp(min=0).sum(1)
    assert (brute > 0).sum() >= 6, "the test poses should include penetrating hands"
    assert (distance.max(1).values > 0).sum() >= 2, "and some links buried beyond their radius"
    assert torch.allclose(result.energy, brute, atol=1e-6, rtol=1e-4)
    assert torch.allclose(result.object_in_hand_max_m, object_in_hand.max(1).values, atol=1e-6)
    assert torch.allclose(result.hand_in_object_max_m, hand_in_object.max(1).values, atol=1e-6)


@pytest.fixture(scope="module")
def fine_sphere_energy(hand, fine_sphere_objects):
    return GraspEnergy.from_assets(hand, [load_asset(fine_sphere_objects, "sphere")], EnergyConfig(object_point_spacing_m=0.002), max_scale=SCALE)


def test_penetration_culling_is_exact_at_box_corners(hand, fine_sphere_energy):
    """A palm-box corner just inside the sphere (the point of a box farthest from its spheres) is not culled."""
    sphere_energy = fine_sphere_energy
    frames = hand.forward(torch.zeros(1, 28))
    rotation, position = hand.shape_frames(frames)
    radius_m = float(sphere_energy.penetration.object_points[0, :256].norm(dim=1).mean()) * SCALE  # the asset is normalized
    poses = []
    for s in torch.nonzero(hand.shape_kind != CAPSULE).flatten().tolist():
        for signs in itertools.product((-1.0, 1.0), repeat=3):
            sign = torch.tensor(signs)
            corner = position[0, s] + rotation[0, s] @ (sign * hand.shape_size[s, :3])
            outward = rotation[0, s] @ sign / math.sqrt(3.0)  # along the box diagonal: the corner is the box part deepest in
            for depth_m in (0.0005, 0.0015, 0.003):
                pose = torch.zeros(28)
                pose[:3] = -(corner + outward * (radius_m - depth_m))  # the sphere, beyond the corner, at the origin
                poses.append(pose)
    pose = torch.stack(poses)
    index, scale = torch.zeros(len(pose), dtype=torch.long), torch.full((len(pose),), SCALE)
    frames = hand.forward(pose)
    result = sphere_energy.penetration(frames, index, scale)
    object_in_hand, weight = _used_object_depths(sphere_energy, hand, frames, index, scale)
    centre = sphere_energy.penetration.sphere_map(frames)
    distance, _ = sphere_energy.bank.signed_distance(centre, index[:, None], scale[:, None])
    brute = object_in_hand.sum(1) * weight + distance.clamp(min=0).sum(1)
    assert (brute > 0).sum() >= len(pose) // 2, "the corners should reach object points"
    assert torch.allclose(result.energy, brute, atol=1e-7, rtol=1e-4)


def test_penetration_far_hand_is_zero_and_inside_is_positive(sphere_energy):
    pose = torch.zeros(2, 28)
    pose[0, :3] = torch.tensor([0.5, 0.5, 0.5])  # far away
    pose[1, :3] = torch.tensor([0.0, 0.0, -0.05])  # palm through the sphere
    result = sphere_energy(pose, object_index=torch.zeros(2, dtype=torch.long), scale=torch.full((2,), SCALE))
    assert result.terms["E_pen"][0].item() == 0.0
    assert result.penetration_mm[0].item() == 0.0
    assert result.terms["E_pen"][1].item() > 0.01
    assert result.penetration_mm[1].item() > 10.0


def test_total_gradient_step_lowers_energy(sphere_energy):
    pose = _poses_near_sphere(8, seed=2).requires_grad_(True)
    kwargs = dict(object_index=torch.zeros(8, dtype=torch.long), scale=torch.full((8,), SCALE))
    contacts = torch.tensor([[5, 40, 75, 135]] * 8)
    result = sphere_energy(pose, contact_index=contacts, **kwargs)
    (grad,) = torch.autograd.grad(result.total.sum(), pose)
    assert torch.isfinite(grad).all() and grad.abs().sum() > 0
    step = 1e-4 * grad / grad.norm(dim=1, keepdim=True)
    after = sphere_energy(pose.detach() - step, contact_index=contacts, **kwargs).total
    assert (after < result.total.detach()).float().mean() >= 0.75


@pytest.mark.parametrize("term", ["E_fc", "E_dis"])
def test_gradient_matches_finite_differences(sphere_energy, term):
    """Autograd through kinematics and the SDF agrees with central differences (steps inside one voxel)."""
    pose = _poses_near_sphere(1, seed=3)
    contacts = torch.tensor([[5, 40, 75, 135]])
    kwargs = dict(object_index=torch.zeros(1, dtype=torch.long), scale=torch.full((1,), SCALE), contact_index=contacts)

    def energy(p):
        return sphere_energy(p, **kwargs).terms[term]

    x = pose.clone().requires_grad_(True)
    (grad,) = torch.autograd.grad(energy(x).sum(), x)
    h = 2e-4
    for coordinate in (0, 2, 4, 7):
        plus, minus = pose.clone(), pose.clone()
        plus[0, coordinate] += h
        minus[0, coordinate] -= h
        numeric = (energy(plus) - energy(minus)).item() / (2 * h)
        assert grad[0, coordinate].item() == pytest.approx(numeric, rel=0.02, abs=0.01)


def test_evaluate_grasp_energies_reports_missing_objects(hand, sphere_objects):
    pose = _poses_near_sphere(3, seed=4).numpy()
    grasps = GraspSet(
        {"hand_pose": pose, "object_id": np.array(["sphere", "box", "nope"], dtype=object), "scale": np.full(3, SCALE, np.float32)}
    )
    out = evaluate_grasp_energies(grasps, sphere_objects, device="cpu", batch_size=2, config=EnergyConfig(object_point_spacing_m=0.003), hand=hand, contact_samples=256)
    assert np.isfinite(out["E_fc"][:2]).all() and np.isnan(out["E_fc"][2])
    assert out["energy_failure_reason"][2].startswith("object asset unusable")
    assert out["energy_failure_reason"][0] == ""
    assert (out["contact_index"][:2] >= 0).all()
    assert out["contact_distance_mm"][0] * 4 == pytest.approx(out["E_dis"][0] * 1000, rel=1e-4)
    # Without given contacts, the searched set is never worse than the four nearest the surface (the default).
    nearest = evaluate_grasp_energies(grasps.select(np.arange(2)), sphere_objects, config=EnergyConfig(object_point_spacing_m=0.003), hand=hand, contact_samples=0)
    searched = out["E_fc"][:2] + 100 * out["E_dis"][:2]
    assert (searched <= nearest["E_fc"] + 100 * nearest["E_dis"] + 1e-5).all()
    again = evaluate_grasp_energies(grasps, sphere_objects, batch_size=2, config=EnergyConfig(object_point_spacing_m=0.003), hand=hand, contact_samples=256)
    assert np.array_equal(again["contact_index"], out["contact_index"])


def _dense_reference_terms(energy, hand, pose, object_index, scale, contact_index):
    """Every term the straightforward way: all candidates, all object points against all shapes, all keypoint pairs."""
    frames = hand.forward(pose)
    candidates = hand.contact_candidates(frames)
    points = torch.gather(candidates, 1, contact_index[..., None].expand(-1, -1, 3))
    distance, normal = energy.bank.signed_distance(points, object_index[:, None], scale[:, None])
    depth, weight = _used_object_depths(energy, hand, frames, object_index, scale)
    object_in_hand = depth.sum(1) * weight
    spheres = energy.penetration.spheres
    centre_distance, _ = energy.bank.signed_distance(frames.transform(spheres.centre_local, spheres.link), object_index[:, None], scale[:, None])
    pairs = torch.triu(hand.keypoint_pair_mask, diagonal=1).nonzero(as_tuple=True)
    return {
        "E_fc": ForceClosureTerm()(points, normal),
        "E_dis": distance.abs().sum(1),
        "E_pen": object_in_hand + centre_distance.clamp(min=0).sum(1),
        "E_spen": _dense_self_penetration(hand.penetration_keypoints(frames), pairs, 0.02),
        "E_joints": JointLimitTerm(hand.joint_limits)(pose[:, 6:]),
    }


def test_energy_and_gradient_equal_the_dense_reference(hand, sphere_energy):
    """The culled, sparse-gradient evaluation equals the dense one (both objects, three scales, curled fingers)."""
    count = 48
    pose = _poses_near_sphere(count, seed=5)
    pose[::2, 6:] = 1.3 * torch.rand(count // 2, 22, generator=torch.Generator().manual_seed(6))  # fingers curled into each other
    pose[-1, :3] = 0.5  # one hand far from its object: nothing near, nothing culled wrongly
    object_index = torch.arange(count) % 2
    scale = torch.tensor([0.07, 0.08, 0.09])[torch.arange(count) % 3]
    contacts = torch.randint(0, 140, (count, 4), generator=torch.Generator().manual_seed(7))
    weights = sphere_energy.weights

    x = pose.clone().requires_grad_(True)
    result = sphere_energy(x, object_index=object_index, scale=scale, contact_index=contacts)
    (grad,) = torch.autograd.grad(result.total.sum(), x)
    y = pose.clone().requires_grad_(True)
    reference = _dense_reference_terms(sphere_energy, hand, y, object_index, scale, contacts)
    (reference_grad,) = torch.autograd.grad(combined_energy(weights, reference).sum(), y)

    assert (reference["E_pen"] > 1e-4).sum() >= 10 and (reference["E_spen"] > 0).sum() >= 5, "the poses should exercise both terms"
    for name, value in reference.items():
        assert torch.allclose(result.terms[name], value, rtol=1e-5, atol=1e-7), name
    assert result.terms["E_pen"][-1].item() == 0.0
    assert torch.allclose(grad, reference_grad, rtol=1e-4, atol=1e-5 * float(reference_grad.abs().max()))


def test_point_clusters_cover_every_point_once_within_their_radius(sphere_energy):
    from dexlite_pipeline.energy.point_clusters import build_point_clusters

    from dexlite_pipeline.energy.point_clusters import LEAVES_PER_PARENT, PADDING

    points = sphere_energy.penetration.object_points
    counts = (points < PADDING / 2).all(-1).sum(-1)
    assert counts[0] != counts[1], "the two objects' sequences differ in length (one is padded)"
    clusters = build_point_clusters(points, leaf_size=8, counts=counts)
    assert clusters.members.shape[2] <= 8 and clusters.radius.shape[1] % LEAVES_PER_PARENT == 0
    for o in range(len(points)):
        members = clusters.members[o]
        valid = members >= 0
        assert torch.equal(members[valid].sort().values, torch.arange(int(counts[o])))  # every real point once, no padding
        spread = (points[o][members.clamp(min=0)] - clusters.centre[o][:, None]).norm(dim=-1)
        assert (spread[valid] <= clusters.radius[o][:, None].expand_as(spread)[valid]).all()
        # every cluster's sphere inside its parent's
        parent = torch.arange(clusters.radius.shape[1]) // LEAVES_PER_PARENT
        reach = (clusters.centre[o] - clusters.parent_centre[o][parent]).norm(dim=-1) + clusters.radius[o]
        real = (members >= 0).any(dim=1)
        assert (reach[real] <= clusters.parent_radius[o][parent][real]).all()


def test_batch_with_nothing_near_the_object(sphere_energy):
    """Every culling stage empty: E_pen is zero and the gradient of the rest still flows."""
    pose = torch.zeros(3, 28)
    pose[:, :3] = 0.5
    x = pose.requires_grad_(True)
    kwargs = dict(object_index=torch.tensor([0, 1, 0]), scale=torch.full((3,), SCALE), contact_index=torch.zeros(3, 4, dtype=torch.long))
    result = sphere_energy(x, **kwargs)
    (grad,) = torch.autograd.grad(result.total.sum(), x)
    assert result.terms["E_pen"].tolist() == [0.0, 0.0, 0.0] and result.penetration_mm.tolist() == [0.0, 0.0, 0.0]
    assert torch.isfinite(grad).all() and grad.abs().sum() > 0


def test_total_is_the_weighted_sum_of_the_named_terms(sphere_energy):
    """Terms are named objects weighted by their key; one more object in the list is one more weighted term."""
    import copy
    from dataclasses import fields

    from dexlite_pipeline.energy.config import EnergyWeights
    from dexlite_pipeline.energy.grasp_energy import TERM_NAMES
    from dexlite_pipeline.energy.terms import EnergyTerm

    assert tuple(term.name for term in sphere_energy.terms) == TERM_NAMES
    assert {term.weight_key for term in sphere_energy.terms} <= {f.name for f in fields(EnergyWeights)}

    class PalmHeight(EnergyTerm):
        name = "E_height"
        weight_key = "dis"

        def evaluate(self, context):
            return context.frames.translation[:, 0, 2].abs()

    pose = _poses_near_sphere(6, seed=11)
    index, scale = torch.zeros(6, dtype=torch.long), torch.full((6,), SCALE)
    base = sphere_energy(pose, object_index=index, scale=scale)
    assert torch.equal(base.total, combined_energy(sphere_energy.weights, base.terms))
    extended = copy.copy(sphere_energy)
    extended.terms = [*sphere_energy.terms, PalmHeight()]
    result = extended(pose, object_index=index, scale=scale, contact_index=base.contact_index)
    assert set(result.terms) == {*TERM_NAMES, "E_height"}
    expected = base.total + sphere_energy.weights.dis * pose[:, 2].abs()
    assert torch.allclose(result.total, expected, rtol=1e-6)
