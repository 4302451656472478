"""The penetration measure against exact mesh distances: a thin-walled bowl and a box at real size.

The reference ("exact") depth of a grasp is two-sided and dense: the deepest of 2,000 surface
points per hand shape inside the mesh (exact point-to-mesh distance) and the deepest of 200,000
mesh surface points inside the hand's analytic capsules and boxes.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from dexlite_pipeline.energy.config import EnergyConfig
from dexlite_pipeline.energy.grasp_energy import GraspEnergy
from dexlite_pipeline.hand import ShadowHand
from dexlite_pipeline.objects.assets import load_asset
from dexlite_pipeline.objects.mesh_distance import MeshDistance

FINGERTIP_LINK = "robot0:ffdistal"


def _real_size_assets(root, meshes: dict, resolution: int = 48) -> None:
    """Assets whose normalized frame is metres (grasp scale 1): the SDF voxel is then (extent + 6 cm) / 47."""
    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    settings = AssetBuildSettings(sdf_resolution=resolution, sdf_padding=0.03, surface_points=2000)
    for object_id, mesh in meshes.items():
        write_asset(mesh, object_id, root, settings, {"source": "test"}, convex_pieces=[mesh.convex_hull])


@pytest.fixture(scope="module")
def real_size_objects(tmp_path_factory):
    import trimesh

    from dexlite_pipeline.objects.household import build_bowl

    root = tmp_path_factory.mktemp("real_size_objects")
    bowl = build_bowl(height=0.07, rim_radius=0.08, base_radius=0.04, wall=0.004, base_thickness=0.005, roundness=1.0)
    assert bowl.is_watertight
    box = trimesh.creation.box(extents=(0.27, 0.19, 0.07))
    _real_size_assets(root, {"bowl": bowl, "box": box})
    return root, {"bowl": bowl, "box": box}


@pytest.fixture(scope="module")
def dense_hand():
    return ShadowHand(surface_points_per_shape=2000)


def exact_depth_m(dense_hand, mesh, pose: torch.Tensor) -> np.ndarray:
    """(B,) reference depth (m) of grasps at scale 1 (module docstring)."""
    import trimesh

    frames = dense_hand.forward(pose)
    distance = MeshDistance.from_mesh(mesh.vertices, mesh.faces)
    hand_points = dense_hand.surface_points(frames).detach().numpy()
    hand_in_object = np.stack([distance.query(p)[0].max() for p in hand_points])
    samples, _ = trimesh.sample.sample_surface(mesh, 200_000, seed=1)
    object_points = torch.as_tensor(samples, dtype=torch.float32)[None]
    object_in_hand = np.array([  # one grasp at a time: 200,000 points against 18 shapes
        float(dense_hand.collision_signed_distance(dense_hand.forward(pose[i : i + 1]), object_points).max()) for i in range(len(pose))
    ])
    return np.maximum(np.maximum(hand_in_object, object_in_hand), 0.0)


def _fingertip_poses(hand, surface_points: np.ndarray, normals: np.ndarray, depths_m: np.ndarray) -> torch.Tensor:
    """Poses whose index fingertip sphere sits ``depth`` into the surface at each point, approaching along −normal.

    The palm keeps one orientation relative to the normal (the finger points into the surface),
    the other fingers curled away.
    """
    from dexlite_pipeline.energy.spheres import build_hand_spheres
    from dexlite_pipeline.hand.rotation import matrix_to_euler_xyz

    spheres = build_hand_spheres(hand)
    link = hand.link_names.index(FINGERTIP_LINK)
    tip = int(torch.nonzero(spheres.link == link).flatten()[-1])  # the last sphere of the distal capsule: the tip
    joints = torch.zeros(22)
    for finger in range(1, 4):  # MF, RF, LF flexed out of the way
        joints[4 * finger + 1 : 4 * finger + 4] = 1.4
    joints[19], joints[18] = 1.2, 1.0  # thumb across the palm
    base = torch.cat([torch.zeros(6), joints])[None]
    frames = hand.forward(base)
    tip_palm = frames.transform(spheres.centre_local[tip : tip + 1], spheres.link[tip : tip + 1])[0, 0]
    finger_axis = frames.rotation[0, link] @ torch.tensor([0.0, 0.0, 1.0])  # the distal capsule's axis, palm frame
    radius = float(spheres.radius[tip])
    poses = []
    for point, normal, depth in zip(surface_points, normals, depths_m):
        # Rotate the palm so the finger axis points along −n (into the surface).
        rotation = torch.as_tensor(Rotation.align_vectors(-normal[None], finger_axis.numpy()[None])[0].as_matrix(), dtype=torch.float32)
        centre = torch.as_tensor(point + normal * (radius - float(depth)), dtype=torch.float32)
        translation = centre - rotation @ tip_palm
        poses.append(torch.cat([translation, matrix_to_euler_xyz(rotation[None])[0], joints]))
    return torch.stack(poses)


def _measure(energy: GraspEnergy, pose: torch.Tensor, term: str = "judge"):
    """The judged measure (``judge``: 2 mm points, mesh distances) or E_pen's own term (``penetration``) at scale 1."""
    index = torch.zeros(len(pose), dtype=torch.long)
    with torch.no_grad():
        return getattr(energy, term)(energy.hand.forward(pose), index, torch.ones(len(pose)), exact=term == "judge")


def _outer_wall_points(mesh, count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Surface points of the bowl's outer wall (normals pointing outward and sideways) with their normals."""
    rng = np.random.default_rng(seed)
    points, faces = _sample(mesh, 20_000, seed)
    normals = mesh.face_normals[faces]
    radial = np.linalg.norm(points[:, :2], axis=1)
    outward = (np.einsum("ij,ij->i", normals[:, :2], points[:, :2]) / np.maximum(radial, 1e-9) > 0.7) & (points[:, 2] > 0.015)
    choice = rng.choice(np.flatnonzero(outward), count, replace=False)
    return points[choice], normals[choice]


def _sample(mesh, count, seed):
    import trimesh

    return trimesh.sample.sample_surface(mesh, count, seed=seed)


@pytest.fixture(scope="module")
def bowl_energy(real_size_objects):
    root, _ = real_size_objects
    return GraspEnergy.from_assets(ShadowHand(), [load_asset(root, "bowl")], EnergyConfig(), max_scale=1.0)


def test_thin_wall_touch_is_measured_within_half_a_millimetre(bowl_energy, real_size_objects, dense_hand):
    """A fingertip pressed 0.5-3 mm into a 4 mm bowl wall from outside: the measure agrees with the exact depth."""
    _, meshes = real_size_objects
    points, normals = _outer_wall_points(meshes["bowl"], 12, seed=0)
    depths = np.linspace(0.0005, 0.003, len(points))
    pose = _fingertip_poses(bowl_energy.hand, points, normals, depths)
    exact = exact_depth_m(dense_hand, meshes["bowl"], pose)
    measured = _measure(bowl_energy, pose).depth_m.numpy()
    assert np.abs(exact - depths).max() < 0.0008, "the reference should see the depth the poses were built with"
    error = np.abs(measured - exact)
    assert np.percentile(error, 90) <= 0.0005 and error.max() <= 0.001, (measured, exact)


def test_finger_through_the_wall_fails_the_start_check(bowl_energy, real_size_objects):
    """A fingertip whose centre lies inside the 4 mm wall: the wall passes through the finger (depth ≈ r + 2 mm)."""
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.sim.config import LiftConfig
    from dexlite_pipeline.sim.lift import run_lift_tests

    root, meshes = real_size_objects
    points, normals = _outer_wall_points(meshes["bowl"], 3, seed=1)
    radius = 0.00705
    through = _fingertip_poses(bowl_energy.hand, points, normals, np.full(3, radius + 0.002))  # centre 2 mm inside the wall
    touching = _fingertip_poses(bowl_energy.hand, points, normals, np.full(3, 0.001))
    depth = _measure(bowl_energy, torch.cat([through, touching])).depth_m.numpy()
    assert (depth[:3] > 0.008).all() and (np.abs(depth[3:] - 0.001) < 0.0005).all(), depth
    grasps = GraspSet({"hand_pose": torch.cat([through, touching]).numpy(), "object_id": np.full(6, "bowl", dtype=object), "scale": np.ones(6, np.float32)})
    result = run_lift_tests(grasps, root, LiftConfig(close_s=0.02, hold_s=0.0, lift_s=0.02, final_hold_s=0.0))
    assert list(result["failure_reason"][:3]) == ["initial_penetration"] * 3
    assert not any(reason == "initial_penetration" for reason in result["failure_reason"][3:])
    assert np.allclose(result["initial_penetration_mm"], depth * 1000, atol=1e-3)


def test_large_box_buried_fingertip_is_seen(real_size_objects, dense_hand):
    """A 27 cm box with fingertips 4 mm deep in its top: points per area see each one in E_pen and the depth matches
    the exact one; 2,000 points per object (one per ~80 mm² here) under-read how deep the object is in the finger."""
    root, meshes = real_size_objects
    box = load_asset(root, "box")
    hand = ShadowHand()
    rng = np.random.default_rng(2)
    top = np.column_stack([rng.uniform(-0.1, 0.1, 8), rng.uniform(-0.07, 0.07, 8), np.full(8, 0.035)])
    pose = _fingertip_poses(hand, top, np.tile([0.0, 0.0, 1.0], (8, 1)), np.full(8, 0.004))
    dense = GraspEnergy.from_assets(hand, [box], EnergyConfig(), max_scale=1.0)
    measured = _measure(dense, pose)
    exact = exact_depth_m(dense_hand, meshes["box"], pose)
    assert np.abs(measured.depth_m.numpy() - exact).max() <= 0.0005
    assert (_measure(dense, pose, "penetration").energy.numpy() > 0.001).all(), "E_pen above its 1 mm threshold for every buried fingertip"
    area = float(meshes["box"].area)
    sparse = GraspEnergy.from_assets(hand, [box], EnergyConfig(object_point_spacing_m=(area / 2000) ** 0.5), max_scale=1.0)
    under_read = exact - _measure(sparse, pose, "penetration").object_in_hand_max_m.numpy()
    assert (under_read > 0.0005).sum() >= 4, "2,000 points should miss the deepest part of most tips (the test's premise)"


def test_contact_resolution_backs_buried_fingertips_out_to_the_allowed_depth(real_size_objects):
    """Fingertips 3-6 mm into the box's top and the bowl's wall end within 1.5 mm (judged); grasps already within are untouched."""
    from dexlite_pipeline.optim.contact_resolution import resolve_contacts

    root, meshes = real_size_objects
    hand = ShadowHand()
    rng = np.random.default_rng(3)
    top = np.column_stack([rng.uniform(-0.1, 0.1, 6), rng.uniform(-0.07, 0.07, 6), np.full(6, 0.035)])
    depths = np.array([0.003, 0.004, 0.006, 0.0005, 0.001, 0.005])
    pose = _fingertip_poses(hand, top, np.tile([0.0, 0.0, 1.0], (6, 1)), depths)
    box = GraspEnergy.from_assets(hand, [load_asset(root, "box")], EnergyConfig(), max_scale=1.0)
    index, scale = torch.zeros(6, dtype=torch.long), torch.ones(6)
    resolved = resolve_contacts(box, pose, index, scale, allowed_m=0.0015)
    assert np.allclose(resolved.depth_before_m.numpy(), depths, atol=0.0005)
    assert (resolved.depth_m.numpy() <= 0.0015 + 1e-6).all(), resolved.depth_m
    clear = depths <= 0.0015
    assert torch.equal(resolved.hand_pose[clear], pose[clear]) and (resolved.steps[clear] == 0).all()
    assert np.allclose(_measure(box, resolved.hand_pose).depth_m.numpy(), resolved.depth_m.numpy(), atol=1e-6)
    # still touching: backed out to the allowed depth, not far away
    assert (resolved.depth_m.numpy()[~clear] > 0.0005).all()
    points, normals = _outer_wall_points(meshes["bowl"], 4, seed=4)
    bowl = GraspEnergy.from_assets(hand, [load_asset(root, "bowl")], EnergyConfig(), max_scale=1.0)
    wall = resolve_contacts(bowl, _fingertip_poses(hand, points, normals, np.full(4, 0.004)), torch.zeros(4, dtype=torch.long), torch.ones(4), 0.0015)
    assert (wall.depth_m.numpy() <= 0.0015 + 1e-6).all()


def test_contact_resolution_steps_grow_with_the_excess_depth(real_size_objects, monkeypatch):
    """Fingertips 6-9 mm into the box's top back out in fewer steps than with base steps only, to the same end: within
    1.5 mm and still touching (the last steps, within a millimetre of done, are base steps)."""
    from dexlite_pipeline.optim import contact_resolution

    root, _ = real_size_objects
    hand = ShadowHand()
    rng = np.random.default_rng(5)
    top = np.column_stack([rng.uniform(-0.1, 0.1, 4), rng.uniform(-0.07, 0.07, 4), np.full(4, 0.035)])
    pose = _fingertip_poses(hand, top, np.tile([0.0, 0.0, 1.0], (4, 1)), np.array([0.006, 0.007, 0.008, 0.009]))
    box = GraspEnergy.from_assets(hand, [load_asset(root, "box")], EnergyConfig(), max_scale=1.0)
    index, scale = torch.zeros(4, dtype=torch.long), torch.ones(4)
    grown = contact_resolution.resolve_contacts(box, pose, index, scale, allowed_m=0.0015)
    monkeypatch.setattr(contact_resolution, "MAX_STEP_GROWTH", 1.0)
    base = contact_resolution.resolve_contacts(box, pose, index, scale, allowed_m=0.0015)
    for resolved in (grown, base):
        assert ((resolved.depth_m.numpy() <= 0.0015 + 1e-6) & (resolved.depth_m.numpy() > 0.0005)).all(), resolved.depth_m
    assert (grown.steps < base.steps).all(), (grown.steps, base.steps)


def test_contact_resolution_lifts_the_hand_out_of_the_table(real_size_objects):
    """On a table, resolution also ends every grasp wholly above it (the lift test's own check), still within the
    allowed depth in the object; a grasp clear of both is untouched, and without a table nothing moves for it."""
    from dexlite_pipeline.energy.table_clearance import HandTableClearance, hand_table_depth
    from dexlite_pipeline.objects.rest_pose import SupportPlane
    from dexlite_pipeline.optim.contact_resolution import resolve_contacts
    from dexlite_pipeline.tabletop import SupportPlanes

    root, _ = real_size_objects
    hand = ShadowHand()
    top = np.tile([0.03, -0.02, 0.035], (4, 1))
    pose = _fingertip_poses(hand, top, np.tile([0.0, 0.0, 1.0], (4, 1)), np.array([0.001, 0.003, 0.001, 0.0]))
    normal = np.array([0.2, -0.1, 1.0]) / np.linalg.norm([0.2, -0.1, 1.0])  # a table tilted against the object frame
    pose[2:, :3] += torch.as_tensor(normal * 0.05, dtype=pose.dtype)  # the last two start 5 cm higher: clear of the table
    lowest = HandTableClearance(hand).lowest_heights(hand.forward(pose), torch.as_tensor(np.tile(normal, (4, 1)), dtype=pose.dtype), torch.zeros(4))
    plane = SupportPlane(tuple(normal), -float(lowest[:2].min(dim=1).values.max()) - 0.002)  # the first two 2 mm or more below it
    before = hand_table_depth(hand, pose.numpy(), plane, np.ones(4))
    assert (before[:2] >= 0.002 - 1e-6).all() and (before[2:] == 0).all(), before
    tabletop = GraspEnergy.from_assets(hand, [load_asset(root, "box")], EnergyConfig(), max_scale=1.0, support_planes=SupportPlanes({"box": plane}))
    index, scale = torch.zeros(4, dtype=torch.long), torch.ones(4)

    resolved = resolve_contacts(tabletop, pose, index, scale, allowed_m=0.0015)

    after = hand_table_depth(hand, resolved.hand_pose.numpy(), plane, np.ones(4))
    assert (after <= 1e-6).all(), after  # the lift test's tolerance (tabletop.TABLE_TOLERANCE_M)
    assert np.allclose(resolved.table_depth_m.numpy(), after, atol=1e-6)
    assert (resolved.depth_m.numpy() <= 0.0015 + 1e-6).all(), resolved.depth_m
    assert (resolved.steps[:2] > 0).all() and (resolved.steps[2:] == 0).all() and torch.equal(resolved.hand_pose[2:], pose[2:])
    floating = GraspEnergy.from_assets(hand, [load_asset(root, "box")], EnergyConfig(), max_scale=1.0)
    without_table = resolve_contacts(floating, pose, index, scale, allowed_m=0.0015)
    assert (without_table.table_depth_m == 0).all() and torch.equal(without_table.hand_pose[[0, 2, 3]], pose[[0, 2, 3]])


def test_one_pass_excess_and_depth_match_the_separate_measures(real_size_objects):
    """Contact resolution reads its depths and both excesses from one pass: the same values as the judged depth and
    ``excess`` for the whole hand and for the palm's shapes alone."""
    from dexlite_pipeline.optim.contact_resolution import PALM_LINK

    root, _ = real_size_objects
    hand = ShadowHand()
    rng = np.random.default_rng(8)
    top = np.column_stack([rng.uniform(-0.1, 0.1, 6), rng.uniform(-0.07, 0.07, 6), np.full(6, 0.035)])
    pose = _fingertip_poses(hand, top, np.tile([0.0, 0.0, 1.0], (6, 1)), np.array([0.0, 0.001, 0.002, 0.004, 0.006, 0.03]))
    box = GraspEnergy.from_assets(hand, [load_asset(root, "box")], EnergyConfig(), max_scale=1.0)
    index, scale = torch.zeros(6, dtype=torch.long), torch.ones(6)
    palm = hand.shape_link == hand.link_names.index(PALM_LINK)
    frames = hand.forward(pose.clone().requires_grad_(True))
    whole, palm_only, depth = box.judge.excess_and_depth(frames, index, scale, 0.0015, palm)
    assert torch.equal(depth, box.judged_depth_m(hand.forward(pose), index, scale))
    assert torch.equal(whole, box.judge.excess(frames, index, scale, 0.0015))
    assert torch.equal(palm_only, box.judge.excess(frames, index, scale, 0.0015, shapes=palm))
    assert (whole[depth <= 0.0015] == 0).all() and (whole[depth > 0.0015] > 0).all()
    assert (palm_only <= whole).all()
