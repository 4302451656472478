"""What a hand description derives from its MJCF: joints, contact candidates, palm frame, pre-grasp; and the files it refuses.

The Shadow Hand's derived pad sides are checked against the sides ``ShadowHand`` was written with
(palmar -y on the fingers, -x on the thumb), which the derivation never reads.
"""

from __future__ import annotations

import numpy as np
import pytest
from three_finger import THREE_FINGER_XML, write_three_finger

from dexlite_pipeline.hand import JOINT_NAMES
from dexlite_pipeline.hand.description import CONTACTS_PER_LINK, HandDescriptionError, hand_description


def test_the_shadow_description_has_shadowhands_joints_limits_and_collision_shapes(hand):
    description = hand_description("shadow")
    assert description.joint_names == JOINT_NAMES
    np.testing.assert_allclose(description.joint_limits, hand.joint_limits.numpy(), atol=1e-6)
    assert description.links == hand.link_names
    assert len(description.shapes) == len(hand.shape_kind)
    np.testing.assert_allclose([s.pos for s in description.shapes], hand.shape_pos.numpy(), atol=1e-7)


def test_the_derived_pad_sides_of_the_shadow_hand_are_the_palmar_sides_shadowhand_was_written_with():
    description = hand_description("shadow")
    for link in ("robot0:ffmiddle", "robot0:ffdistal", "robot0:lfdistal", "robot0:thmiddle", "robot0:thdistal"):
        normals = description.contact_normals[description.contact_link == description.links.index(link)]
        palmar = np.array([-1.0, 0.0, 0.0]) if link.startswith("robot0:th") else np.array([0.0, -1.0, 0.0])
        assert len(normals) == CONTACTS_PER_LINK and np.all(normals @ palmar > np.cos(np.radians(40))), link
    np.testing.assert_allclose(description.approach, [0.0, -1.0, 0.0], atol=1e-4)  # the palm faces -y
    assert description.opposing == ("robot0:thdistal",)


def test_the_shadow_hands_fingers_get_candidates_on_the_links_shadowhand_was_written_with():
    """The proximal, middle and distal phalanx of each of the four fingers, the thumb's middle and distal (its hub has no
    collision geom), beside the palm's."""
    from dexlite_pipeline.hand.model import ShadowHand

    shadow = ShadowHand()
    written = {shadow.link_names[i] for i in shadow.contact_link.tolist()}
    derived = set(hand_description("shadow").candidates_per_link())
    fingers = {link for link in written if not link.startswith("robot0:th")}
    assert fingers == {f"robot0:{f}{p}" for f in ("ff", "mf", "rf", "lf") for p in ("proximal", "middle", "distal")}
    assert derived - {"robot0:palm"} == written


@pytest.mark.parametrize("name, approach, along, thumb, kp", [
    ("allegro", (1.0, 0.0, 0.0), (0.0, 0.0, 1.0), "th_tip", 1.0),
    ("leap", (0.0, 0.0, -1.0), (1.0, 0.0, 0.0), "th_ds", 3.0),
])  # fmt: skip
def test_allegro_and_leap_descriptions(name, approach, along, thumb, kp):
    description = hand_description(name)
    assert len(description.joints) == 16 and all(j.actuator and j.kp == kp for j in description.joints)
    assert description.opposing == (thumb,)
    assert description.approach @ np.array(approach) > np.cos(np.radians(6))  # LEAP's: 5.0 deg toward its fingers
    assert description.palm_frame[:3, 0] @ np.array(along) > np.cos(np.radians(6))
    np.testing.assert_allclose(description.palm_frame[:3, :3].T @ description.palm_frame[:3, :3], np.eye(3), atol=1e-12)
    counts = description.candidates_per_link()
    assert all(0 < c <= CONTACTS_PER_LINK for link, c in counts.items() if link != "palm") and counts["palm"] > 0
    for finger in description.fingers:  # every finger has candidates on its last three jointed links
        assert sum(link in counts for link in finger) >= 3
    low, high = description.joint_limits.T
    assert np.all((low <= description.pregrasp) & (description.pregrasp <= high))


def test_contact_candidates_lie_on_their_links_collision_surface_facing_the_pad_side():
    description = hand_description("allegro")
    for point, link in zip(description.contact_points, description.contact_link):
        samples = np.concatenate([s.points for s in description.shapes if s.link == description.links[link]])
        assert np.min(np.linalg.norm(samples - point, axis=1)) < 1e-12  # a sample of the link's own shapes
    # Allegro's fingers curl toward the palm's +x: the fingertip candidates face +x at the zero pose.
    tip = description.contact_normals[description.contact_link == description.links.index("ff_tip")]
    assert np.all(tip[:, 0] > np.cos(np.radians(36)))


def test_a_face_behind_another_surface_of_its_link_is_recessed_and_gets_no_candidates():
    """A sample with its link's surface 3 mm in front of it (within 6 mm of its normal line) is recessed; 1 mm in front,
    or 3 mm in front but 10 mm to the side, it is not. ``facing`` leaves recessed samples out unless all are."""
    from dexlite_pipeline.hand.derive import LinkSurface, facing, recessed

    up = np.array([0.0, 0.0, 1.0])
    plate = np.array([[x, y, 0.0] for x in np.linspace(-0.004, 0.004, 5) for y in np.linspace(-0.004, 0.004, 5)])
    points = np.array([[0.0, 0.0, -0.003], [0.0, 0.0, -0.001], [0.010, 0.0, -0.003]])
    assert recessed(points, np.tile(up, (3, 1)), plate).tolist() == [True, False, False]
    surface = LinkSurface(np.concatenate([plate, points]), np.tile(up, (len(plate) + 3, 1)), np.zeros(len(plate) + 3, dtype=int))
    kept, _ = facing(surface, up, lambda p, s: np.zeros(len(p), dtype=bool), 40)
    assert len(kept) == len(plate) + 2 and not np.any(np.all(np.isclose(kept, points[0]), axis=1))
    only_recessed = LinkSurface(points[:1], up[None], np.zeros(1, dtype=int))
    assert len(facing(only_recessed, up, lambda p, s: np.zeros(len(p), dtype=bool), 10)[0]) == 1


def test_leaps_candidates_lie_on_faces_an_object_can_touch():
    """No candidate of LEAP (whose thumb tip and palm have faces in the gaps between their boxes, up to 42 mm behind
    the front) has its link's surface more than 2 mm in front of it."""
    from dexlite_pipeline.hand.derive import RECESS_RADIUS_M, RECESSED_M

    description = hand_description("leap")
    for point, normal, link in zip(description.contact_points, description.contact_normals, description.contact_link):
        samples = np.concatenate([s.points for s in description.shapes if s.link == description.links[link]]) - point
        ahead = samples @ normal
        lateral = np.linalg.norm(samples - ahead[:, None] * normal, axis=1)
        assert ahead[lateral < RECESS_RADIUS_M].max() <= RECESSED_M + 1e-9, description.links[link]


def test_the_three_finger_test_hand_loads_through_the_same_path(tmp_path):
    description = hand_description(write_three_finger(tmp_path))
    assert description.name == "three_finger"
    assert description.joint_names == tuple(f"{f}_j{k}" for f in ("f1", "f2", "th") for k in range(3))
    assert [j.kp for j in description.joints if j.actuator] == [2.0]
    assert {s.kind for s in description.shapes} == {"box", "capsule"} and len(description.shapes) == 10
    assert set(description.candidates_per_link()) == {"palm", "f10", "f11", "f12", "f20", "f21", "f22", "th0", "th1", "th2"}
    np.testing.assert_allclose(description.approach, [0.0, 0.0, -1.0], atol=1e-4)
    np.testing.assert_allclose(description.palm_frame[:3, 3][2], -0.01, atol=1e-9)  # on the palm's -z face
    assert np.all(description.contact_normals[description.contact_link == 0] @ [0.0, 0.0, -1.0] > 0.99)


def _write(tmp_path, text: str, name: str = "hand.xml"):
    path = tmp_path / name
    path.write_text(text) if isinstance(text, str) else path.write_bytes(text)
    return path


@pytest.mark.parametrize("text, reason", [
    ("this is not xml <", "not XML"),
    (b"\x89PNG\r\n\x1a\n\x00\x00", "not XML"),
    ('<robot name="r"><link name="a"/></robot>', "not an MJCF file: its root element is <robot>"),
    ('<mujoco><worldbody><body name="a"><geom type="capsule" size="0.01"/></body></worldbody></mujoco>', "MuJoCo cannot compile it"),
    ('<mujoco><worldbody><body name="a"><geom type="box" size="0.01 0.01 0.01"/></body></worldbody></mujoco>', "no joints"),
    (THREE_FINGER_XML.replace('<geom name="palm_box"', '<geom contype="0" conaffinity="0" name="palm_box"')
     .replace('size="0.008"/>', 'size="0.008" contype="0" conaffinity="0"/>'), "no collision geoms"),
    ('<mujoco><worldbody><body name="a"><freejoint/><geom type="box" size="0.01 0.01 0.01"/></body></worldbody></mujoco>',
     "only hinge joints are supported, the model has free joints"),
    (THREE_FINGER_XML.replace('range="-0.2 1.57"', 'limited="false"'), "has no range"),
])  # fmt: skip
def test_a_file_that_cannot_describe_a_hand_is_refused_in_one_line(tmp_path, text, reason):
    with pytest.raises(HandDescriptionError) as error:
        hand_description(_write(tmp_path, text))
    assert reason in str(error.value) and "\n" not in str(error.value)


def test_a_missing_file_is_refused(tmp_path):
    with pytest.raises(HandDescriptionError, match="no such file"):
        hand_description(tmp_path / "absent.xml")
