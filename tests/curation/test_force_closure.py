"""Force closure of a grasp's actual contacts: wrench-hull ε on hand-built contact sets, and the link contacts of real poses."""

import math

import numpy as np
import pytest
import torch

from dexlite_pipeline.curation.force_closure import ContactModel, contact_wrenches, epsilon_quality, evaluate_force_closure, link_contacts
from dexlite_pipeline.io.grasp_store import GraspSet


def _epsilon(points, friction, edges=8):
    """ε of contacts on a unit sphere at ``points`` (outward normal = the point itself)."""
    points = np.asarray(points, float)
    normals = points / np.linalg.norm(points, axis=1, keepdims=True)
    return epsilon_quality(contact_wrenches(points, normals, 1.0, friction, edges))


def _equator(count):
    angles = 2 * math.pi * np.arange(count) / count
    return np.stack([np.cos(angles), np.sin(angles), np.zeros(count)], axis=1)


def test_cone_edges_push_into_the_object_with_unit_normal_component():
    point = np.array([[0.0, 0.0, 1.0]])
    wrenches = contact_wrenches(point, point, 2.0, 0.5, 6)
    assert wrenches.shape == (6, 6)
    np.testing.assert_allclose(wrenches[:, 2], -1.0)  # normal component: into the sphere
    np.testing.assert_allclose(np.linalg.norm(wrenches[:, :2], axis=1), 0.5)  # friction: μ times the normal force
    np.testing.assert_allclose(wrenches[:, 3:], np.cross(point, wrenches[:, :3]) / 2.0)  # torque over the scale


def test_three_contacts_around_a_sphere_close_with_friction_but_not_without():
    assert _epsilon(_equator(3), friction=0.6) > 0.05
    assert _epsilon(_equator(3), friction=0.0) == 0.0  # nothing resists a force along the axis


def test_epsilon_grows_with_friction():
    values = [_epsilon(_equator(3), friction=mu) for mu in (0.2, 0.6, 1.0)]
    assert values[0] < values[1] < values[2]


def test_point_contacts_without_closure_give_zero():
    # Two antipodal point contacts cannot resist a torque about the line joining them.
    assert _epsilon([[1.0, 0, 0], [-1.0, 0, 0]], friction=0.6) == 0.0
    # Contacts on one side only: every force they apply points the same way.
    assert _epsilon([[0.6, 0, 0.8], [-0.6, 0, 0.8], [0, 0.6, 0.8], [0, -0.6, 0.8]], friction=0.6) == 0.0
    # Frictionless contacts through the centre resist no torque at all.
    axes = np.concatenate([np.eye(3), -np.eye(3)])
    assert _epsilon(axes, friction=0.0) == 0.0
    assert _epsilon(np.zeros((0, 3)), friction=0.6) == 0.0


@pytest.fixture(scope="module")
def sphere_dir(tmp_path_factory):
    import trimesh

    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    root = tmp_path_factory.mktemp("force_closure_objects")
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    write_asset(mesh, "sphere", root, AssetBuildSettings(sdf_resolution=32, sdf_padding=0.3, surface_points=500), {"source": "test"}, convex_pieces=[mesh])
    return root


def test_link_contacts_pick_each_links_deepest_point(hand, sphere_dir):
    from dexlite_pipeline.objects.assets import SdfBank, load_asset

    torch.set_num_threads(1)
    bank = SdfBank([load_asset([sphere_dir], "sphere")])
    pose = torch.zeros(3, 28)
    pose[0, :3] = torch.tensor([0.0, 0.0, 1.0])  # 1 m away from a 5 cm sphere: no contact
    pose[:, 9:] = 0.3
    scale = torch.tensor([0.05, 0.05, 5.0])  # the third: a 5 m sphere swallows the whole hand
    pose[1, :3] = torch.tensor([0.0, 0.07, 0.0])
    index = torch.zeros(3, dtype=torch.long)

    def distance_at(link_points):
        return bank.signed_distance(link_points[with_points][None], index[:1], scale[2:])[0]

    points, normals, touching = link_contacts(hand, bank, pose, index, scale, 0.001)
    with_points = torch.zeros(len(hand.link_names), dtype=torch.bool)
    with_points[hand.surface_link] = True  # links with collision shapes; the others can never touch
    assert not touching[0].any()
    assert not touching[:, ~with_points].any()
    assert bool((distance_at(points[2]) > 0.001).all())  # the 5 m sphere holds every link's deepest point,
    assert bool((normals[touching].norm(dim=-1) > 0.5).all())  # but only points with a normal (a cone) are contacts
    surface = hand.surface_points(hand.forward(pose))
    distance, _ = bank.signed_distance(surface, index, scale)
    for link in torch.unique(hand.surface_link).tolist():
        columns = hand.surface_link == link
        deepest = distance[1, columns].argmax()
        torch.testing.assert_close(points[1, link], surface[1, columns][deepest])
        assert bool(touching[1, link]) == bool(distance[1, columns].max() > -0.001)
    near = with_points & (points[1].norm(dim=-1) < 0.06)  # within 1 cm of the 5 cm sphere
    assert near.any()
    radial = points[1, near] / points[1, near].norm(dim=-1, keepdim=True)
    assert bool(((normals[1, near] * radial).sum(-1) > 0.95).all())  # a sphere's outward normal is radial


class _PointHand:
    """A stand-in hand of three one-point links, put where the first nine numbers of the pose say (metres)."""

    device = torch.device("cpu")
    dtype = torch.float32
    link_names = ("first", "second", "third")
    surface_link = torch.arange(3)

    def forward(self, hand_pose):
        return hand_pose

    def surface_points(self, frames):
        return frames[:, :9].reshape(-1, 3, 3)


def test_epsilon_of_a_grasp_set_matches_its_contacts_known_answer(sphere_dir, tmp_path):
    """Three links on the sphere's equator close like the exact contacts there, at any scale; the rest get 0 or NaN with a reason."""
    import shutil

    shutil.copytree(sphere_dir, tmp_path / "objects")
    shutil.copytree(sphere_dir / "assets" / "sphere", tmp_path / "objects" / "assets" / "damaged")
    (tmp_path / "objects" / "assets" / "damaged" / "meta.json").write_text("{not json")
    scales = np.array([0.05, 0.1, 0.05, 0.05, 0.05], np.float32)
    pose = np.zeros((5, 28), np.float32)
    pose[:, :9] = (_equator(3) * scales[:, None, None]).reshape(5, 9)
    pose[2, :9] += 1.0  # a metre away: no contact
    pose[3, 20] = np.nan
    object_id = np.array(["sphere"] * 4 + ["damaged"], dtype=object)
    grasps = GraspSet({"hand_pose": pose, "object_id": object_id, "scale": scales})
    result = evaluate_force_closure(grasps, [tmp_path / "objects"], ContactModel(contact_distance_m=0.001), hand=_PointHand())
    exact = _epsilon(_equator(3), friction=0.6)  # exact radial normals; the grid's normals differ by a few degrees
    assert exact > 0.05
    np.testing.assert_allclose(result.epsilon[:2], exact, rtol=0.02)  # torques over the scale: one answer at every scale
    assert result.epsilon[2] == 0.0 and list(result.failure_reason[:3]) == ["", "", ""]
    assert np.isnan(result.epsilon[3]) and result.failure_reason[3] == "non-finite hand_pose"
    assert np.isnan(result.epsilon[4]) and "object 'damaged'" in result.failure_reason[4] and "meta.json" in result.failure_reason[4]


def test_contact_model_rejects_nonsense():
    with pytest.raises(ValueError, match="cone_edges"):
        ContactModel(cone_edges=2)
    with pytest.raises(ValueError, match="friction"):
        ContactModel(friction=-0.1)

