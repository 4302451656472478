"""Grasp types of optimization from scratch: power grasps unchanged, the precision types' templates, pre-grasp poses,
starts and mix, and the config key."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch

from dexlite_pipeline.config import ConfigError
from dexlite_pipeline.energy.config import EnergyConfig
from dexlite_pipeline.energy.grasp_energy import GraspEnergy
from dexlite_pipeline.objects.rest_pose import SupportPlane
from dexlite_pipeline.optim.config import GraspTypeShares, HopelessStopConfig, InitConfig
from dexlite_pipeline.optim.from_scratch import StartDrawer, synthesize
from dexlite_pipeline.optim.grasp_types import GRASP_TYPES, TYPE_NAMES, assign_types, candidate_group
from dexlite_pipeline.optim.type_starts import PAD_HEIGHT_M, TypeGeometry
from dexlite_pipeline.tabletop import SupportPlanes

from power_baseline import power_run, power_settings, tiny_box_objects

PRECISION = ("pinch", "tripod", "lateral", "rim")
BOX_TABLE = SupportPlanes({"box": SupportPlane((0.0, 0.0, 1.0), 0.3)})  # the box (extents 1.2 x 0.8 x 0.6) lying flat


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    from dexlite_pipeline.objects.assets import load_asset

    root = tiny_box_objects(tmp_path_factory.mktemp("grasp_type_box"))
    return root, [load_asset(root, "box")]


def only(name: str) -> GraspTypeShares:
    return GraspTypeShares(**{n: 1.0 if n == name else 0.0 for n in TYPE_NAMES})


def short_run(**changes):
    """``power_settings`` with the given changes (the tiny run of ``power_baseline``)."""
    return dataclasses.replace(power_settings(), **changes)


def links_of(hand, contact_index: np.ndarray) -> np.ndarray:
    """The link name carrying each contact index, same shape."""
    names = np.asarray(hand.link_names, dtype=object)
    return names[hand.all_contact_link.numpy()[np.asarray(contact_index, dtype=np.int64)]]


# A CPU that rounds float32 otherwise than the one the arrays were saved on (an AMD EPYC against an Intel Xeon) gives
# the same starts and stopping iterations bit for bit, and the same optimized grasps to about 1e-6 of their values,
# except where a contact switch's random acceptance falls the other way on the rounded energy: then that grasp's
# trajectory parts (measured: 1 of the 12 grasps, its energy 0.3% apart). So the starts must be equal, and at least
# ``CLOSE_ROWS_PER_RUN`` of each run's grasps must be the saved ones to float rounding (``CLOSE_RELATIVE`` of the
# array's largest value) with the same contacts.
CLOSE_ROWS_PER_RUN = 5  # of 6
CLOSE_RELATIVE = 1e-4


def test_power_only_run_is_unchanged(box, one_torch_thread):
    """A power-only run draws and optimizes what the code before grasp types did (arrays saved from it), to float rounding."""
    from pathlib import Path

    expected = np.load(Path(__file__).resolve().parents[1] / "fixtures" / "power_baseline.npz")
    got = power_run(box[0])
    for prefix in ("", "keyed_"):
        for name in ("init_pose", "stopped_at_iteration"):
            assert np.array_equal(got[prefix + name], expected[prefix + name]), f"{prefix + name} differs from the run before grasp types"
        close = np.ones(len(expected[prefix + "hand_pose"]), bool)
        for name in ("hand_pose", "E_total"):
            now, saved = np.asarray(got[prefix + name], np.float64), np.asarray(expected[prefix + name], np.float64)
            moved = np.abs(now - saved).reshape(len(saved), -1).max(axis=1) / np.abs(saved).max()
            close &= moved < CLOSE_RELATIVE
        close &= (np.asarray(got[prefix + "contact_index"]) == expected[prefix + "contact_index"]).all(axis=1)
        assert close.sum() >= CLOSE_ROWS_PER_RUN, f"{prefix}run: grasps {np.nonzero(~close)[0].tolist()} differ from the run before grasp types"


def test_power_only_run_records_power(box, one_torch_thread):
    grasps, stats = synthesize(box[1], short_run(grasps_per_object=2, annealing=dataclasses.replace(power_settings().annealing, iterations=2)),
                               EnergyConfig(object_point_spacing_m=0.004), torch.Generator().manual_seed(0), support_planes=BOX_TABLE)
    assert grasps.arrays["grasp_type"].tolist() == ["power"] * 4
    assert stats["grasp_types"] == {"power": 4}


@pytest.mark.parametrize("name", TYPE_NAMES)
def test_each_type_starts_deterministic_per_seed(box, hand, name):
    """The same seed draws the same starts; another seed other starts; all of them above the table."""
    starts = StartDrawer(hand, box[1], short_run(), BOX_TABLE)
    obj, scale = torch.zeros(6, dtype=torch.long), torch.full((6,), 0.1)
    types = torch.full((6,), TYPE_NAMES.index(name))
    support = (torch.tensor([[0.0, 0.0, 1.0]]).expand(6, 3), torch.full((6,), 0.03))

    def draw(seed):
        return starts.draw(obj, scale, types, torch.Generator().manual_seed(seed), support)

    first, again, other = draw(0), draw(0), draw(1)
    assert torch.equal(first, again)
    assert not torch.allclose(first, other)
    assert bool((first[:, 2] + 0.03 >= 0).all())  # palm origins above the table


def test_keyed_starts_of_a_type_do_not_depend_on_the_other_types(box, one_torch_thread):
    """With keyed draws (dexlite grasp) a pinch start is the same in a pinch-only run and in a mix with power."""
    settings = short_run(grasps_per_object=2, annealing=dataclasses.replace(power_settings().annealing, iterations=1),
                         final_contact_samples=0, contact_search_every=0)
    energy = EnergyConfig(object_point_spacing_m=0.004)
    alone, _ = synthesize(box[1], dataclasses.replace(settings, grasp_types=only("pinch")), energy, torch.Generator().manual_seed(0),
                          support_planes=BOX_TABLE, keyed_seed=3)
    mixed, _ = synthesize(box[1], dataclasses.replace(settings, grasps_per_object=4, grasp_types=GraspTypeShares(power=1.0, pinch=1.0)),
                          energy, torch.Generator().manual_seed(0), support_planes=BOX_TABLE, keyed_seed=3)
    assert mixed.arrays["grasp_type"].tolist() == ["power", "pinch"] * 4
    pinch_rows = mixed.arrays["grasp_type"] == "pinch"
    assert np.array_equal(mixed.arrays["init_pose"][pinch_rows], alone.arrays["init_pose"])


@pytest.mark.parametrize("keyed_seed", [None, 2])
def test_pinch_contacts_lie_only_on_the_template_links(box, hand, one_torch_thread, keyed_seed):
    """Every contact a pinch grasp holds, at the end of a run with random switches and contact searches, is on its slot's links."""
    settings = short_run(grasps_per_object=4, grasp_types=only("pinch"), stop_hopeless=HopelessStopConfig())
    grasps, _ = synthesize(box[1], settings, EnergyConfig(object_point_spacing_m=0.004), torch.Generator().manual_seed(4),
                           support_planes=BOX_TABLE, keyed_seed=keyed_seed)
    links = links_of(hand, grasps.arrays["contact_index"])
    assert set(links[:, :2].ravel()) == {"robot0:thdistal"}
    assert set(links[:, 2].ravel()) == {"robot0:ffdistal"}
    assert set(links[:, 3].ravel()) <= {"robot0:ffdistal", "robot0:mfdistal"}
    thumb_pad_or_tip = set(candidate_group(hand, "thdistal")) | set(candidate_group(hand, "thdistal:tip"))
    assert set(grasps.arrays["contact_index"][:, :2].ravel().tolist()) <= thumb_pad_or_tip
    assert (grasps.arrays["contact_index"][:, 2:] < hand.pad_candidate_count).all()  # the fingers' pads, not side candidates


def test_pinch_and_tripod_thumb_contacts_may_use_the_thumb_tip_and_power_never(hand):
    """The thumb's two contacts of a pinch or tripod are drawn from its pads and its tip candidates (150–159), the fingers'
    from their pads; a power grasp's draws and its template stay the 140 pads (the power fixture checks the runs bit for bit)."""
    from dexlite_pipeline.optim.grasp_types import contact_slots, contact_template

    tip = set(candidate_group(hand, "thdistal:tip"))
    assert tip == set(range(150, 160))
    uniform = torch.rand(4000, 4, generator=torch.Generator().manual_seed(0))
    for name in ("pinch", "tripod"):
        template = contact_template(hand, GRASP_TYPES[name])
        assert set(template[0]) == set(template[1]) == tip | set(candidate_group(hand, "thdistal"))
        assert not tip & (set(template[2]) | set(template[3]))
        drawn = contact_slots(hand, torch.full((4000,), TYPE_NAMES.index(name))).draw(uniform)
        assert tip <= set(drawn[:, :2].ravel().tolist())  # every tip candidate gets drawn for the thumb
        assert not tip & set(drawn[:, 2:].ravel().tolist())
    assert contact_template(hand, GRASP_TYPES["power"]) == (tuple(range(140)),) * 4
    power = contact_slots(hand, torch.full((4000,), TYPE_NAMES.index("power"))).draw(uniform)
    assert int(power.max()) < hand.pad_candidate_count


def test_lateral_contacts_are_the_thumb_pad_and_the_index_side(box, hand, one_torch_thread):
    settings = short_run(grasps_per_object=4, grasp_types=only("lateral"))
    grasps, _ = synthesize(box[1], settings, EnergyConfig(object_point_spacing_m=0.004), torch.Generator().manual_seed(5), support_planes=BOX_TABLE)
    contacts = grasps.arrays["contact_index"]
    assert set(links_of(hand, contacts[:, :2]).ravel()) == {"robot0:thdistal"}
    assert set(links_of(hand, contacts[:, 2:]).ravel()) == {"robot0:ffmiddle"}
    assert (contacts[:, 2:] >= hand.pad_candidate_count).all()  # the side candidates
    assert set(grasps.arrays["grasp_type"]) == {"lateral"}


def test_assign_types_gives_the_shares_interleaved():
    codes = assign_types({"power": 0.5, "pinch": 0.25, "tripod": 0.25}, 16)
    names = np.asarray(TYPE_NAMES)[codes]
    assert {n: int((names == n).sum()) for n in set(names)} == {"power": 8, "pinch": 4, "tripod": 4}
    shares = {"power": 0.5, "pinch": 0.25, "tripod": 0.25}
    for prefix in range(1, 17):
        for name, share in shares.items():
            assert abs((names[:prefix] == name).sum() - prefix * share) < 1  # every prefix within one start of its share
    odd = np.asarray(TYPE_NAMES)[assign_types({"pinch": 1.0, "lateral": 2.0}, 10)]
    assert sorted(odd.tolist()) == ["lateral"] * 7 + ["pinch"] * 3 or sorted(odd.tolist()) == ["lateral"] * 6 + ["pinch"] * 4
    assert np.array_equal(assign_types(shares, 16), codes)  # a fixed plan


def test_a_mix_deals_each_object_and_scale_in_the_shares(box, one_torch_thread):
    settings = short_run(grasps_per_object=8, grasp_types=GraspTypeShares(power=2.0, pinch=1.0, tripod=1.0, lateral=0.0),
                         annealing=dataclasses.replace(power_settings().annealing, iterations=1), final_contact_samples=0, contact_search_every=0)
    grasps, stats = synthesize(box[1], settings, EnergyConfig(object_point_spacing_m=0.004), torch.Generator().manual_seed(0), support_planes=BOX_TABLE)
    assert stats["grasp_types"] == {"power": 8, "pinch": 4, "tripod": 4}
    for scale in (0.08, 0.1):
        mine = grasps.arrays["grasp_type"][np.isclose(grasps.scale, scale)]
        assert {t: int((mine == t).sum()) for t in set(mine)} == {"power": 4, "pinch": 2, "tripod": 2}


@pytest.mark.parametrize("name", PRECISION)
def test_aperture_pads_face_each_other_with_the_other_fingers_clear(hand, name):
    """The pre-grasp pose opens the type's opposing pads 3–8 cm apart, facing each other, without self-collision."""
    from dexlite_pipeline.energy.terms import SelfPenetrationTerm

    grasp_type = GRASP_TYPES[name]
    opening, facing, self_penetration = pregrasp_pads(hand, grasp_type, grasp_type.aperture_joints())
    assert 0.03 < float(opening.norm()) < 0.08
    assert max(facing) < 20  # the thumb pad faces the other side, and they face the thumb (degrees)
    assert self_penetration < 0.002


def pregrasp_pads(hand, grasp_type, joints):
    """A pre-grasp pose's opening (thumb side to finger side, m), each side's pad normal's angle off it (the finger
    side's reversed; degrees) and its self-penetration energy."""
    from dexlite_pipeline.energy.terms import SelfPenetrationTerm

    pose = torch.zeros(1, 28)
    pose[0, 6:] = joints.float()
    frames = hand.forward(pose)
    table = frames.transform(hand.all_contact_points_local, hand.all_contact_link)[0].double()
    sides = [table[[i for group in side for i in candidate_group(hand, group)]].mean(0) for side in grasp_type.opposition]
    opening = sides[1] - sides[0]

    def pad_normal(group):  # outward normal of a group's pads: from its capsule's axis to the pads
        link = hand.link_index["robot0:" + group.split(":")[0]]
        centre = frames.translation[0, link].double() + frames.rotation[0, link].double() @ hand.shape_pos[hand._capsule_of_link("robot0:" + group.split(":")[0])].double()
        points = table[list(candidate_group(hand, group))]
        radial = points - centre
        axis = frames.rotation[0, link].double()[:, 2]
        radial = radial - (radial @ axis)[:, None] * axis
        mean = (radial / radial.norm(dim=1, keepdim=True)).mean(0)
        return mean / mean.norm()

    unit = opening / opening.norm()
    facing = [math.degrees(math.acos(float(pad_normal(grasp_type.opposition[0][0]) @ unit)))]
    facing += [math.degrees(math.acos(float(-pad_normal(group) @ unit))) for group in grasp_type.opposition[1]]
    return opening, facing, float(SelfPenetrationTerm(hand, 0.02).evaluate_with_torch(frames))


@pytest.mark.parametrize("name", PRECISION)
def test_pregrasp_opens_from_closed_to_wide_with_the_pads_facing(hand, name):
    """Along the pre-grasp blends (closed, aperture, wide) the pads open steadily from at most 2.5 cm to at least twice
    that and beyond the aperture, facing each other within 25° all the way, the hand clear of itself."""
    grasp_type = GRASP_TYPES[name]
    geometry = TypeGeometry(hand, grasp_type)
    assert bool((geometry.widths.diff() > 0).all())
    assert float(geometry.widths[0]) < 0.025 and float(geometry.widths[-1]) > max(2 * float(geometry.widths[0]), geometry.width + 0.01)
    assert torch.equal(geometry.joints[geometry.aperture_index], grasp_type.aperture_joints())
    for blend in (0.0, 0.5, 1.0, 1.5, 2.0):
        opening, facing, self_penetration = pregrasp_pads(hand, grasp_type, grasp_type.pregrasp_joints(blend))
        assert max(facing) < 25 and self_penetration < 0.002, (blend, facing, self_penetration)


def _write_asset(tmp_path, mesh, object_id):
    """``mesh`` (metres, standing on z = 0) written as a normalized asset; returns it and its real scale."""
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    radius = float(np.linalg.norm(mesh.vertices - mesh.bounds.mean(0), axis=1).max())
    normalized = mesh.copy()
    normalized.apply_translation(-mesh.bounds.mean(0))
    normalized.apply_scale(1.0 / radius)
    write_asset(normalized, object_id, tmp_path, AssetBuildSettings(sdf_resolution=24, surface_points=256), {"source": "test"},
                convex_pieces=[normalized.convex_hull])
    return load_asset(tmp_path, object_id), radius


def _pad_starts(hand, asset, scale, name, count=24, seed=0):
    """``count`` starts of type ``name`` on ``asset`` standing on its table (+z up) at ``scale``, without joint noise:
    the thumb-side and finger-side pad centres (count, 3, metres, object frame) and the table's height (m)."""
    from dexlite_pipeline.tabletop import upright_plane

    vertices = np.asarray(asset.load_mesh().vertices)
    planes = SupportPlanes({asset.object_id: upright_plane(vertices, "+z")})
    starts = StartDrawer(hand, [asset], short_run(init=InitConfig(joint_sigma_fraction=0.0)), planes)
    floor = float(vertices[:, 2].min()) * scale
    support = (torch.tensor([[0.0, 0.0, 1.0]]).expand(count, 3), torch.full((count,), -floor))
    pose = starts.draw(torch.zeros(count, dtype=torch.long), torch.full((count,), scale), torch.full((count,), TYPE_NAMES.index(name)),
                       torch.Generator().manual_seed(seed), support)
    table = hand.forward(pose).transform(hand.all_contact_points_local, hand.all_contact_link).double()
    grasp_type = GRASP_TYPES[name]
    sides = [table[:, [i for group in side for i in candidate_group(hand, group)]].mean(1).numpy() for side in grasp_type.opposition]
    return sides[0], sides[1], floor


@pytest.mark.parametrize("name", PRECISION)
def test_a_start_on_a_thin_walled_bowl_straddles_its_wall(tmp_path, hand, name):
    """A 14 cm bowl with a 4 mm wall, 4.5 cm deep, on its table: every start of a precision type puts one pad inside the
    bowl and the other outside, each within 2 cm of the wall, both below the rim and above the table (the rim starts
    put the grasp centre 0.5–3 cm above the rim with the hand's widest opening: pads 3 cm or more from the wall)."""
    import trimesh

    outer = trimesh.creation.revolve([[0, 0], [0.05, 0], [0.07, 0.045], [0, 0.045]], sections=48)
    inner = trimesh.creation.revolve([[0, 0.006], [0.046, 0.006], [0.066, 0.046], [0, 0.046]], sections=48)
    bowl = outer.difference(inner)  # wall 4 mm across (3.6 mm normal to the slanted side), 6 mm base
    asset, scale = _write_asset(tmp_path, bowl, "bowl")
    thumb, finger, floor = _pad_starts(hand, asset, scale, name)
    surface = asset.load_mesh().copy()
    surface.apply_scale(scale)
    rim = float(surface.vertices[:, 2].max())
    wall_at = lambda p: 0.05 + (p[:, 2] - floor) * (0.02 / 0.045) - 0.002  # noqa: E731  mid-wall radius at a pad's height
    radial = [np.linalg.norm(p[:, :2], axis=1) - wall_at(p) for p in (thumb, finger)]
    assert bool((radial[0] * radial[1] < 0).all())  # one inside, one outside
    for r in radial:
        assert bool((np.abs(r) < 0.02 + 0.002).all()) and bool((np.abs(r) > 0.002).all())
    for p in (thumb, finger):
        assert bool((p[:, 2] < rim).all()) and bool((p[:, 2] > floor + PAD_HEIGHT_M - 0.003).all())


def test_rim_starts_spread_three_fingertips_along_and_down_the_wall_around_the_thumb(tmp_path, hand):
    """The rim grasp on a 14 cm bowl with a 4 mm wall: every start (no joint noise) has the index and ring fingertip pads
    2.5–5 cm apart, their line within 35° of the rim's tangent, the thumb's pad between them along it, the middle
    fingertip's pad at least 3 mm lower than their midpoint (on a wall this thin the start opens near the closed pose,
    where the middle is ~8 mm deeper), all three on the wall's other side from the thumb: a triangle around the thumb,
    not the line a pinch or tripod makes (``optim.grasp_types.RIM``)."""
    import trimesh

    outer = trimesh.creation.revolve([[0, 0], [0.05, 0], [0.07, 0.045], [0, 0.045]], sections=48)
    inner = trimesh.creation.revolve([[0, 0.006], [0.046, 0.006], [0.066, 0.046], [0, 0.046]], sections=48)
    asset, scale = _write_asset(tmp_path, outer.difference(inner), "bowl")
    vertices = np.asarray(asset.load_mesh().vertices)
    from dexlite_pipeline.tabletop import upright_plane

    count = 24
    starts = StartDrawer(hand, [asset], short_run(init=InitConfig(joint_sigma_fraction=0.0)),
                         SupportPlanes({asset.object_id: upright_plane(vertices, "+z")}))
    support = (torch.tensor([[0.0, 0.0, 1.0]]).expand(count, 3), torch.full((count,), -float(vertices[:, 2].min()) * scale))
    pose = starts.draw(torch.zeros(count, dtype=torch.long), torch.full((count,), scale), torch.full((count,), TYPE_NAMES.index("rim")),
                       torch.Generator().manual_seed(0), support)
    table = hand.forward(pose).transform(hand.all_contact_points_local, hand.all_contact_link).double().numpy()
    thumb, index, middle, ring = (table[:, list(candidate_group(hand, g))].mean(1) for g in ("thdistal", "ffdistal", "mfdistal", "rfdistal"))
    spread = ring - index
    length = np.linalg.norm(spread, axis=1)
    assert bool(((length > 0.025) & (length < 0.05)).all()), length
    centre = (index + ring) / 2
    tangent = np.stack([-centre[:, 1], centre[:, 0], np.zeros(count)], axis=1)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    along = np.degrees(np.arccos(np.abs((spread / length[:, None] * tangent).sum(1))))
    assert bool((along < 35).all()), along
    assert bool((middle[:, 2] < centre[:, 2] - 0.003).all()), centre[:, 2] - middle[:, 2]
    radius = [np.linalg.norm(p[:, :2], axis=1) for p in (index, middle, ring, thumb)]
    assert bool(all(((r - radius[3]) * (radius[1] - radius[3]) > 0).all() for r in radius[:3]))  # the fingertips on one side
    between = ((thumb - index) * spread).sum(1) / length**2  # the thumb's place along the index-to-ring line
    assert bool(((between > 0.2) & (between < 0.8)).all()), between


def test_a_start_on_a_handle_lying_on_the_table_closes_across_it(tmp_path, hand):
    """A 2.4 cm handle lying on its table: pinch starts come from above with the pads on either side of it, at its
    half height, each within 2 cm of it (not on its top, not under it)."""
    import trimesh

    handle = trimesh.creation.cylinder(radius=0.012, height=0.2, sections=32)
    handle.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, (0, 1, 0)))
    handle.apply_translation((0, 0, 0.012))
    asset, scale = _write_asset(tmp_path, handle, "handle")
    thumb, finger, floor = _pad_starts(hand, asset, scale, "pinch")
    # the handle's axis along x at height 0.012 above the table, centred at the asset's origin
    across = [p[:, 1] for p in (thumb, finger)]
    assert bool((across[0] * across[1] < 0).all())
    for side in across:
        assert bool((np.abs(side) > 0.012).all()) and bool((np.abs(side) < 0.012 + 0.02).all())
    for p in (thumb, finger):
        assert bool((np.abs(p[:, 2] - floor - 0.012) < 0.012).all())  # beside it: between the table and its top


def test_low_objects_are_approached_from_above_palm_down(tmp_path, hand):
    """A 3 cm slab on its table: every pinch start comes from above (the approach within the jitter of straight down),
    its grasp centre and palm above the table, its opening across the rim (horizontal within the jitter)."""
    import trimesh

    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    slab = trimesh.creation.box(extents=(1.6, 1.2, 0.3))  # normalized; at scale 0.1: 16 x 12 x 3 cm
    write_asset(slab, "slab", tmp_path, AssetBuildSettings(sdf_resolution=24, surface_points=256), {"source": "test"}, convex_pieces=[slab])
    assets = [load_asset(tmp_path, "slab")]
    planes = SupportPlanes({"slab": SupportPlane((0.0, 0.0, 1.0), 0.15)})
    starts = StartDrawer(hand, assets, short_run(init=InitConfig(joint_sigma_fraction=0.1)), planes)
    count = 32
    support = (torch.tensor([[0.0, 0.0, 1.0]]).expand(count, 3), torch.full((count,), 0.015))
    pose = starts.draw(torch.zeros(count, dtype=torch.long), torch.full((count,), 0.1), torch.full((count,), TYPE_NAMES.index("pinch")),
                       torch.Generator().manual_seed(0), support).double()
    from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix

    geometry = TypeGeometry(hand, GRASP_TYPES["pinch"])
    rotation = euler_xyz_to_matrix(pose[:, 3:6])
    approach, opening = rotation @ geometry.approach, rotation @ geometry.opening
    jitter = math.radians(GRASP_TYPES["pinch"].jitter_deg)
    assert bool((approach[:, 2] <= -math.cos(jitter) + 1e-6).all())
    assert bool((opening[:, 2].abs() <= math.sin(jitter) + 1e-6).all())
    centre = pose[:, :3] + rotation @ geometry.centre
    assert bool((centre[:, 2] > -0.015).all()) and bool((pose[:, 2] > -0.015).all())


def test_grasp_type_shares_config():
    from dexlite_pipeline.settings import build_config

    config = build_config({"optimize_grasps": {"grasp_types": {"power": 0.0, "pinch": 3.0, "rim": 1.0}}})
    assert config.optimize_grasps.grasp_types.shares() == {"power": 0.0, "pinch": 3.0, "tripod": 0.0, "lateral": 0.0, "rim": 1.0}
    assert build_config({}).optimize_grasps.grasp_types.shares() == {"power": 1.0, "pinch": 0.0, "tripod": 0.0, "lateral": 0.0, "rim": 0.0}
    with pytest.raises(ConfigError, match=r"^optimize_grasps.grasp_types: every share is 0"):
        build_config({"optimize_grasps": {"grasp_types": {"power": 0.0}}})
    with pytest.raises(ConfigError, match=r"optimize_grasps.grasp_types.pinch"):
        GraspTypeShares(pinch=-1.0)
    with pytest.raises(ConfigError, match=r"grasp_types: unknown key\(s\) grip"):
        build_config({"optimize_grasps": {"grasp_types": {"grip": 1.0}}})


def test_config_names_every_grasp_type():
    assert tuple(GraspTypeShares().shares()) == TYPE_NAMES


# A pinch touches the object with the thumb, index and middle fingertips (its template) and, beside them, at most
# those fingers' middle phalanges; never the palm, the ring or little finger, or a proximal phalanx.
PINCH_TOUCH = {f"robot0:{finger}{part}" for finger in ("th", "ff", "mf") for part in ("distal", "middle")}
TOUCH_M = 0.002  # a hand surface point this close to the object surface, or inside it, touches


def touching_links(hand, grasps, asset) -> list[set[str]]:
    """Per grasp, the links with a surface point within ``TOUCH_M`` of the object's surface or inside it."""
    energy = GraspEnergy.from_assets(hand, [asset], EnergyConfig(object_point_spacing_m=0.004))
    pose = torch.as_tensor(grasps.hand_pose)
    points = hand.surface_points(hand.forward(pose))
    depth, _ = energy.bank.signed_distance(points, torch.zeros(len(pose), 1, dtype=torch.long), torch.as_tensor(grasps.scale)[:, None])
    names = np.asarray(hand.link_names, dtype=object)[hand.surface_link.cpu().numpy()]
    return [set(names[(row > -TOUCH_M).numpy()].tolist()) for row in depth]


def scratch_grasps(assets, grasp_type: str, n: int):
    """``n`` grasps of the box at scale 0.1 on its table by ``dexlite grasp --grasp-type``'s optimization from scratch
    (the top-up, --from-scratch), 300 iterations."""
    from dexlite_pipeline.api import typed_config
    from dexlite_pipeline.tools.grasp.checks import tool_config
    from dexlite_pipeline.tools.grasp.synthesis import synthesize_from_scratch

    config, _ = tool_config(typed_config({"optimize_grasps": {"annealing": {"iterations": 300}}}, grasp_type))
    return synthesize_from_scratch(assets, {"box": (0.1,)}, n, config, torch.device("cpu"), 0, support_planes=BOX_TABLE)


def assert_only_pinches(hand, grasps, asset) -> None:
    """Every grasp is a pinch and touches the object, only with the pinch's fingers (``PINCH_TOUCH``)."""
    assert set(grasps.arrays["grasp_type"]) == {"pinch"}
    touched = touching_links(hand, grasps, asset)
    assert all(links and links <= PINCH_TOUCH for links in touched), [sorted(links - PINCH_TOUCH) for links in touched]


def test_grasp_type_pinch_makes_only_pinches_touching_with_the_pinch_fingers(box, hand, one_torch_thread):
    """``dexlite grasp --grasp-type pinch``'s optimization from scratch: every grasp is a pinch and touches the box only with
    the pinch's fingertips and the phalanges beside them; power grasps asked the same way do not."""
    assert_only_pinches(hand, scratch_grasps(box[1], "pinch", 8), box[1][0])
    powers = scratch_grasps(box[1], "power", 8)
    assert any(links - PINCH_TOUCH for links in touching_links(hand, powers, box[1][0]))  # the check tells a power grasp apart


def test_a_model_trained_on_pinches_and_power_grasps_asked_for_pinches_gives_only_pinches(box, hand, one_torch_thread, tmp_path):
    """``dexlite grasp --model M --grasp-type pinch``: a tiny model trained on the box's pinch and power grasps (made by
    optimization from scratch) samples pinches, refined with the pinch's template, that touch the box only with the pinch's
    fingers; asked for power grasps it gives grasps that touch with others."""
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.model.checkpoint import load_checkpoint, save_checkpoint
    from dexlite_pipeline.model.config import ModelConfig, TrainConfig
    from dexlite_pipeline.model.data import build_training_data
    from dexlite_pipeline.model.training import fit_training_codes, grasp_energy_terms, train_cvae
    from dexlite_pipeline.tools.grasp.checks import tool_config
    from dexlite_pipeline.tools.grasp.synthesis import synthesize_with_model

    keep = ("hand_pose", "object_id", "scale", "grasp_type", "contact_index")
    made = GraspSet.concatenate([GraspSet({k: scratch_grasps(box[1], name, 12).arrays[k] for k in keep}) for name in ("pinch", "power")])
    data = build_training_data(made, box[1], hand)
    network = ModelConfig(pointnet_widths=(16, 32, 64, 32), encoder_hidden=(64, 64), decoder_hidden=(64, 64), latent_dim=8, normalization="none")
    train = TrainConfig(model=network, epochs=100, max_steps=0, batch_size=8, clouds_per_batch=1, points_per_cloud=64, validation_fraction=0.0,
                        lr_warmup_steps=0)
    everything = np.arange(len(made))
    energy = GraspEnergy.from_assets(hand, box[1], EnergyConfig(object_point_spacing_m=0.005))
    result = train_cvae(data, everything, np.zeros(0, np.int64), train, grasp_energy_terms(energy), seed=0)
    fit_training_codes(result.model, data, everything, train)
    save_checkpoint(tmp_path / "cvae.pt", result.model, train, {"seed": 0}, training_grasps={**made.arrays})
    loaded = load_checkpoint(tmp_path / "cvae.pt")
    assert loaded[0].type_vocabulary == ("pinch", "power")

    def sampled(grasp_type: str):
        post = {"annealing": {"iterations": 200}, "budget_iterations": [0], "stop_hopeless": {"iterations": [], "max_e_fc": [], "max_e_dis_m": []}}
        config, _ = tool_config({"sample": {"grasp_type": grasp_type, "yaw_candidates": 1}, "post_optimize": post})
        return synthesize_with_model(box[1], {"box": (0.1,)}, 8, config, loaded, str(tmp_path / "cvae.pt"), torch.device("cpu"), seed=0,
                                     support_planes=BOX_TABLE)

    assert_only_pinches(hand, sampled("pinch"), box[1][0])
    assert any(links - PINCH_TOUCH for links in touching_links(hand, sampled("power"), box[1][0]))
