"""Optimization from scratch with a hand from its MJCF: the tests' three-finger hand (15-number poses) on a cylinder,
and Allegro's starts on a table."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from described_hands import CYLINDER_ID, three_finger_hand, write_objects  # noqa: E402

from dexlite_pipeline.energy.config import EnergyConfig  # noqa: E402
from dexlite_pipeline.energy.grasp_energy import GraspEnergy  # noqa: E402
from dexlite_pipeline.objects.assets import load_asset  # noqa: E402
from dexlite_pipeline.optim.config import AnnealingSchedule, GraspTypeShares, OptimizeGraspsConfig  # noqa: E402

ENERGY = EnergyConfig(object_point_spacing_m=0.004)


@pytest.fixture(scope="module")
def setting(tmp_path_factory):
    root = write_objects(tmp_path_factory.mktemp("described_objects"))
    return three_finger_hand(tmp_path_factory.mktemp("hand")), [load_asset(root, CYLINDER_ID)]


def short_config(**changes) -> OptimizeGraspsConfig:
    base = OptimizeGraspsConfig()
    return dataclasses.replace(base, grasps_per_object=6, scales=(0.06,), batch_size=6,
                               annealing=AnnealingSchedule(iterations=150, step_size_period=17, temperature_period=10), trace_every=10,
                               **changes)


def test_optimization_from_scratch_lowers_the_energy_of_the_three_finger_hand(setting, one_torch_thread):
    """The starts (15 numbers: palm, nine joints) walk down the energy: the kept state's total falls for every grasp."""
    from dexlite_pipeline.optim.annealing import optimize
    from dexlite_pipeline.optim.from_scratch import StartDrawer

    hand, assets = setting
    config = short_config()
    energy = GraspEnergy.from_assets(hand, assets, ENERGY, max_scale=0.06)
    object_index, scale = torch.zeros(6, dtype=torch.long), torch.full((6,), 0.06)
    init = StartDrawer(hand, assets, config).draw(object_index, scale, torch.zeros(6, dtype=torch.long), torch.Generator().manual_seed(3), None)
    assert init.shape == (6, 15)
    limits = hand.joint_limits
    assert bool(((init[:, 6:] >= limits[:, 0]) & (init[:, 6:] <= limits[:, 1])).all())
    result = optimize(energy, init, object_index, scale, config.optimizer_config(), torch.Generator().manual_seed(4))
    assert result.hand_pose.shape == (6, 15) and torch.isfinite(result.hand_pose).all()
    assert bool((result.trace[-1] <= result.trace[0]).all()) and float(result.trace[-1].median()) < 0.5 * float(result.trace[0].median())


def test_synthesize_takes_the_hand_and_keeps_its_pose_length(setting, one_torch_thread):
    from dexlite_pipeline.optim.from_scratch import synthesize

    hand, assets = setting
    grasps, stats = synthesize(assets, short_config(), ENERGY, torch.Generator().manual_seed(0), hand=hand)
    assert grasps.hand_pose.shape == (6, 15) and grasps.arrays["init_pose"].shape == (6, 15) and stats["grasps"] == 6
    assert np.isfinite(grasps.arrays["E_total"]).all() and grasps.arrays["grasp_type"].tolist() == ["power"] * 6


def test_a_grasp_type_the_hand_does_not_offer_is_refused(setting):
    """The three-finger hand has no finger opposing the others, so no precision type (``optim.described_types``)."""
    from dexlite_pipeline.optim.from_scratch import synthesize

    hand, assets = setting
    config = short_config(grasp_types=GraspTypeShares(power=0.5, pinch=0.5))
    with pytest.raises(ValueError, match="grasp type pinch is not defined for this hand"):
        synthesize(assets, config, ENERGY, torch.Generator().manual_seed(0), hand=hand)


def test_allegro_starts_face_the_object_from_above_the_table(setting):
    """Allegro's starts: the palm frame's origin above the table, its palm normal toward the object (within the tilt
    toward the fingers and the jitter)."""
    from dexlite_pipeline.hand.described import DescribedHand
    from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix
    from dexlite_pipeline.optim.from_scratch import StartDrawer

    _, assets = setting
    hand = DescribedHand("allegro")
    count = 32
    support = (torch.tensor([[0.0, 0.0, 1.0]]).expand(count, 3), torch.full((count,), 0.6 * 0.06))
    init = StartDrawer(hand, assets, short_config()).draw(torch.zeros(count, dtype=torch.long), torch.full((count,), 0.06),
                                                          torch.zeros(count, dtype=torch.long), torch.Generator().manual_seed(1), support)
    assert init.shape == (count, 22)
    rotation = euler_xyz_to_matrix(init[:, 3:6].double())
    frame = torch.as_tensor(hand.palm_frame_local)
    palm_origin = (rotation @ frame[:3, 3, None])[..., 0] + init[:, :3].double()
    assert bool((palm_origin[:, 2] + 0.6 * 0.06 > 0).all())
    normal = (rotation @ frame[:3, 2, None])[..., 0]
    toward = -torch.nn.functional.normalize(palm_origin, dim=1)  # to the object's centre
    assert float(((normal * toward).sum(1) > 0.5).float().mean()) > 0.9


@pytest.mark.parametrize("name", ["allegro", "leap"])
def test_the_start_turns_only_the_thumb_to_face_the_fingers(name, one_torch_thread):
    """The opposed start moves the opposing finger's joints only, inside their limits, and its candidates face the other
    fingers' candidates more directly than the curled start's (mean cosine; Allegro 0.93 -> 0.96, LEAP 0.90 -> 0.98)."""
    from dexlite_pipeline.hand.described import DescribedHand
    from dexlite_pipeline.optim.init import curled_pregrasp, opposed_pregrasp

    hand = DescribedHand(name)
    curled, opposed = curled_pregrasp(hand), opposed_pregrasp(hand)
    thumb = [f for f, links in enumerate(hand.finger_links) if hand.link_index[hand.description.opposing[0]] in links][0]
    moved = torch.nonzero(opposed != curled).flatten().tolist()
    assert moved and set(moved) <= set(hand.finger_joints[thumb])
    limits = hand.joint_limits.double()
    assert bool(((opposed >= limits[:, 0]) & (opposed <= limits[:, 1])).all())

    def facing(joints):
        frames = hand.forward_parts_torch(torch.eye(3)[None], torch.zeros(1, 3), joints[None].float())
        points = frames.transform(hand.contact_points_local, hand.contact_link)[0].double()
        normals = (frames.rotation[0, hand.contact_link].double() @ torch.as_tensor(hand.description.contact_normals)[..., None])[..., 0]
        on_thumb = torch.isin(hand.contact_link, torch.tensor(hand.finger_links[thumb]))
        others = ~on_thumb & (hand.contact_link != 0)
        toward = points[others].mean(0) - points[on_thumb]
        return float((normals[on_thumb] * toward / toward.norm(dim=-1, keepdim=True)).sum(-1).mean())

    assert facing(opposed) > facing(curled) + 0.03 and facing(opposed) > 0.95


@pytest.mark.parametrize("name", ["allegro", "leap"])
def test_the_start_approach_puts_the_thumb_tip_and_the_fingertips_equally_far(name, one_torch_thread):
    """At the opposed start the thumb's tip and the other fingers' tips lie equally far along the start's approach, which
    stays near the palm normal (LEAP 4°, Allegro 7° off it); along the Shadow Hand's 30° tilt the fingertips are ahead."""
    import math

    from dexlite_pipeline.hand.described import DescribedHand
    from dexlite_pipeline.optim.init import PALM_TILT_DEG, balanced_approach, opposed_pregrasp

    hand = DescribedHand(name)
    approach = torch.as_tensor(balanced_approach(hand), dtype=torch.float64)
    assert abs(float(approach.norm()) - 1.0) < 1e-9
    normal = torch.as_tensor(hand.palm_frame_local[:3, 2], dtype=torch.float64)
    assert math.degrees(math.acos(float(approach @ normal))) < 10.0
    frames = hand.forward_parts_torch(torch.eye(3)[None], torch.zeros(1, 3), opposed_pregrasp(hand)[None].float())
    points = frames.transform(hand.contact_points_local, hand.contact_link)[0].double()
    thumb = hand.link_index[hand.description.opposing[0]]
    tips = [points[hand.contact_link == links[-1]].mean(0) for links in hand.finger_links]
    thumb_tip = torch.stack([t for t, links in zip(tips, hand.finger_links) if thumb in links]).mean(0)
    finger_tips = torch.stack([t for t, links in zip(tips, hand.finger_links) if thumb not in links]).mean(0)
    assert abs(float((finger_tips - thumb_tip) @ approach)) < 1e-6
    tilted = torch.as_tensor(hand.approach_local(PALM_TILT_DEG), dtype=torch.float64)
    assert float((finger_tips - thumb_tip) @ tilted) > 0.03


def test_a_hand_without_an_opposing_finger_starts_curled(tmp_path):
    from dexlite_pipeline.optim.init import curled_pregrasp, opposed_pregrasp

    hand = three_finger_hand(tmp_path)
    assert hand.description.opposing == ()
    assert torch.equal(opposed_pregrasp(hand), curled_pregrasp(hand))
    from dexlite_pipeline.optim.init import PALM_TILT_DEG, balanced_approach

    assert np.array_equal(balanced_approach(hand), hand.approach_local(PALM_TILT_DEG))


def test_a_described_hands_power_grasps_keep_one_contact_on_its_opposing_finger(tmp_path, one_torch_thread):
    """LEAP's power slots: the first contact among the thumb's candidates, the others among every pad; the Shadow Hand
    and a hand without an opposing finger draw any pad in every slot (None)."""
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.hand.described import DescribedHand
    from dexlite_pipeline.optim.grasp_types import power_slots, slots_of_types

    assert power_slots(ShadowHand("cpu"), 4) is None and slots_of_types(ShadowHand("cpu"), ["power"] * 4) is None
    assert power_slots(three_finger_hand(tmp_path), 4) is None
    leap = DescribedHand("leap")
    slots = power_slots(leap, 64)
    thumb = {leap.link_index[name] for finger in leap.description.fingers if finger[-1] == "th_ds" for name in finger}
    drawn = slots.draw(torch.rand(64, 4, generator=torch.Generator().manual_seed(0), dtype=torch.float64))
    links = leap.contact_link[drawn]
    assert all(int(link) in thumb for link in links[:, 0])
    assert {int(link) for link in links[:, 1:].flatten()} - thumb  # the other three reach beyond the thumb
    assert slots.counts[0].tolist() == [len(leap.opposing_candidates()), 140, 140, 140]
    assert slots_of_types(leap, ["power"] * 2).counts.tolist() == slots.counts[:2].tolist()
