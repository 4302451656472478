"""Grasp types of hands read from their MJCF (``optim.described_types``): which types a hand offers, its fitted
pre-grasp poses, and optimization from scratch with a precision type keeping its contacts on the template's links."""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from described_hands import CYLINDER_ID, three_finger_hand, write_objects  # noqa: E402

from dexlite_pipeline.energy.config import EnergyConfig  # noqa: E402
from dexlite_pipeline.energy.terms import SelfPenetrationTerm  # noqa: E402
from dexlite_pipeline.objects.assets import load_asset  # noqa: E402
from dexlite_pipeline.objects.rest_pose import SupportPlane  # noqa: E402
from dexlite_pipeline.optim.config import AnnealingSchedule, GraspTypeShares, OptimizeGraspsConfig  # noqa: E402
from dexlite_pipeline.optim.described_types import OPENINGS_M  # noqa: E402
from dexlite_pipeline.optim.grasp_types import TYPE_NAMES, check_hand_offers, hand_grasp_types  # noqa: E402
from dexlite_pipeline.tabletop import SupportPlanes  # noqa: E402

PRECISION = ("pinch", "tripod", "rim")


@pytest.fixture(scope="module")
def hands():
    from dexlite_pipeline.hand.described import DescribedHand

    return {name: DescribedHand(name, dtype=torch.float64) for name in ("leap", "allegro")}


def test_the_types_of_a_float32_hand_are_fitted_as_those_of_a_float64_one(tmp_path):
    """The fit runs in float64 on a copy of the description, whatever the dtype of the hand asked (the runs' hands are
    float32): fitted afresh from either, the types are the same."""
    from dexlite_pipeline.hand.described import DescribedHand
    from dexlite_pipeline.optim import described_types

    described_types._FITTED.clear()
    single = hand_grasp_types(DescribedHand("allegro"))
    described_types._FITTED.clear()
    assert hand_grasp_types(DescribedHand("allegro", dtype=torch.float64)) == single


def test_allegro_and_leap_offer_the_precision_types_and_a_hand_without_a_thumb_power_only(hands, tmp_path):
    """Both hands have one thumb and three fingers: power, pinch, tripod and rim (no lateral: no side candidates); the
    tests' three-finger hand has no finger opposing the others: power only, and asking it for a pinch is refused in one
    line naming the hand and the type."""
    for hand in hands.values():
        assert tuple(hand_grasp_types(hand)) == ("power", *PRECISION)
    little = three_finger_hand(tmp_path)
    assert tuple(hand_grasp_types(little)) == ("power",)
    with pytest.raises(ValueError, match=r"hand three_finger: grasp type pinch is not defined for this hand \(it offers power\)"):
        check_hand_offers(little, ["power", "pinch"])
    check_hand_offers(hands["leap"], ["rim", "power"])
    with pytest.raises(ValueError, match="grasp type lateral is not defined"):
        check_hand_offers(hands["leap"], ["lateral"])


def test_the_templates_oppose_the_thumb_to_the_index_finger_first(hands):
    """The pinch's finger side is the index finger (LEAP's ``if``, Allegro's ``ff``: the end of the row nearer the thumb),
    the tripod's the index and middle, the rim's all three; the thumb side its last jointed link and the fixed tip below."""
    expected = {"leap": ("th_ds",), "allegro": ("th_distal", "th_tip")}
    index = {"leap": "if", "allegro": "ff"}
    for name, hand in hands.items():
        types = hand_grasp_types(hand)
        for grasp_type in types.values():
            if grasp_type.opposition is not None:
                assert grasp_type.opposition[0] == expected[name]
        fingers = lambda t: {link.split("_")[0] for link in types[t].opposition[1]}  # noqa: E731
        assert fingers("pinch") == {index[name]} and fingers("tripod") == {index[name], "mf"} and fingers("rim") == {index[name], "mf", "rf"}


def _sides(hand, grasp_type, joints: torch.Tensor):
    """The opening between the two sides' mean candidate positions (m), each side's mean pad normal's angle off the line
    between them (degrees; the finger side per finger), and E_spen, at pre-grasp ``joints`` (J,)."""
    description = hand.description
    pose = torch.zeros(1, 6 + len(joints), dtype=torch.float64)
    pose[0, 6:] = joints
    frames = hand.forward(pose)
    points = torch.as_tensor(np.asarray(description.contact_points), dtype=torch.float64)
    normals = torch.as_tensor(np.asarray(description.contact_normals), dtype=torch.float64)
    link = np.asarray(description.contact_link)

    def side(names):
        rows = np.isin(link, [hand.link_index[n] for n in names]).nonzero()[0]
        rot = frames.rotation[0, link[rows]]
        p = (rot @ points[rows, :, None])[..., 0] + frames.translation[0, link[rows]]
        n = (rot @ normals[rows, :, None])[..., 0].mean(0)
        return p.mean(0), n / n.norm()

    thumb_p, thumb_n = side(grasp_type.opposition[0])
    fingers: dict[str, list[str]] = {}
    for name in grasp_type.opposition[1]:
        fingers.setdefault(name.split("_")[0], []).append(name)
    finger = [side(names) for names in fingers.values()]
    axis = torch.stack([p for p, _ in finger]).mean(0) - thumb_p
    unit = axis / axis.norm()
    angles = [math.degrees(math.acos(float(thumb_n @ unit)))] + [math.degrees(math.acos(float(-n @ unit))) for _, n in finger]
    return float(axis.norm()), angles, float(SelfPenetrationTerm(hand).evaluate_with_torch(frames)[0])


@pytest.mark.parametrize("type_name", PRECISION)
def test_fitted_pregrasps_open_steadily_from_closed_to_wide_with_the_sides_facing(hands, type_name):
    """Closed, aperture and wide at the type's openings (within 3 mm); the opening grows along the blends; every side's pad
    normal within 40° of the line to the other side at closed, aperture and wide; no self-penetration beyond 2 mm summed."""
    for hand in hands.values():
        grasp_type = hand_grasp_types(hand)[type_name]
        aperture_m, closed_m, wide_m = OPENINGS_M[type_name]
        openings = []
        for blend in np.linspace(0.0, 2.0, 9):
            opening, angles, spen = _sides(hand, grasp_type, grasp_type.pregrasp_joints(float(blend)))
            openings.append(opening)
            assert spen < 0.002, (hand.description.name, type_name, blend, spen)
            if blend in (0.0, 1.0, 2.0):
                assert max(angles) < 40.0, (hand.description.name, type_name, blend, angles)
        assert openings[0] == pytest.approx(closed_m, abs=0.003) and openings[4] == pytest.approx(aperture_m, abs=0.003)
        assert openings[-1] == pytest.approx(wide_m, abs=0.003)
        assert all(b > a for a, b in zip(openings, openings[1:])), (hand.description.name, type_name, openings)


@pytest.fixture(scope="module")
def standing_cylinder(tmp_path_factory):
    root = write_objects(tmp_path_factory.mktemp("described_type_objects"))
    return [load_asset(root, CYLINDER_ID)], SupportPlanes({CYLINDER_ID: SupportPlane((0.0, 0.0, 1.0), 0.6)})


def test_leap_pinches_from_scratch_keep_their_contacts_on_the_template_links(hands, standing_cylinder, one_torch_thread):
    """LEAP asked for pinches: every grasp records pinch, its pose has 22 numbers, its first two contacts lie on the thumb's
    tip link, the third on the index fingertip, the fourth on the index or middle fingertip; its starts differ from power's."""
    from dexlite_pipeline.hand.described import DescribedHand
    from dexlite_pipeline.optim.from_scratch import synthesize

    hand = DescribedHand("leap")
    assets, planes = standing_cylinder
    config = dataclasses.replace(
        OptimizeGraspsConfig(), grasps_per_object=4, scales=(0.05,), batch_size=4, trace_every=10,
        annealing=AnnealingSchedule(iterations=40, step_size_period=17, temperature_period=10),
        grasp_types=GraspTypeShares(**{n: 1.0 if n == "pinch" else 0.0 for n in TYPE_NAMES}),
    )
    grasps, stats = synthesize(assets, config, EnergyConfig(object_point_spacing_m=0.004), torch.Generator().manual_seed(0),
                               support_planes=planes, hand=hand)
    assert grasps.arrays["grasp_type"].tolist() == ["pinch"] * 4 and stats["grasp_types"] == {"pinch": 4}
    assert grasps.hand_pose.shape == (4, 22) and np.isfinite(grasps.arrays["E_total"]).all()
    names = np.asarray(hand.link_names, dtype=object)[hand.all_contact_link.numpy()[grasps.arrays["contact_index"].astype(np.int64)]]
    assert set(names[:, :2].ravel()) == {"th_ds"} and set(names[:, 2]) == {"if_ds"} and set(names[:, 3]) <= {"if_ds", "mf_ds"}
