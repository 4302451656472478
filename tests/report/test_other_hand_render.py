"""Pictures and the 3-D view of a hand from its MJCF (the tests' three-finger hand): its collision shapes drawn where its
kinematics put them, the store's recorded hand chosen for ``dexlite render``, the gallery and the view."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from image_colours import colour_fraction
from report_synthetic import OBJECT_ID

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "hand"))

from three_finger import write_three_finger  # noqa: E402

from dexlite_pipeline.cli import main  # noqa: E402
from dexlite_pipeline.io.grasp_store import GraspSet, write_grasp_store  # noqa: E402
from dexlite_pipeline.report.render import HAND_RGB, OBJECT_RGB, described_hand_visual, hand_mesh_world, hand_of_store  # noqa: E402

POSE_WIDTH = 6 + 9


@pytest.fixture(scope="module")
def three_finger(tmp_path_factory):
    """The three-finger hand's file and its ``DescribedHand``."""
    from dexlite_pipeline.hand.described import DescribedHand

    xml = write_three_finger(tmp_path_factory.mktemp("three_finger_render"))
    return xml, DescribedHand(xml)


def above_the_box(count: int) -> np.ndarray:
    """``count`` poses of the three-finger hand 6 cm above the origin (the box's centre), palm (facing -z) down, joints 0."""
    poses = np.zeros((count, POSE_WIDTH), np.float32)
    poses[:, 2] = 0.06
    poses[:, 0] = np.linspace(-0.01, 0.01, count)
    return poses


def test_each_collision_shape_is_drawn_where_its_surface_samples_are(three_finger):
    _, hand = three_finger
    description = hand.description
    visual = described_hand_visual(description)
    assert visual.faces.max() < len(visual.vertices) and set(np.unique(visual.vertex_link)) <= set(range(len(description.links)))
    assert len({shape.link for shape in description.shapes}) == len(description.shapes)  # one shape per link here
    for shape in description.shapes:
        drawn = visual.vertices[visual.vertex_link == description.links.index(shape.link)]
        samples = np.asarray(shape.points)
        assert np.allclose(drawn.min(axis=0), samples.min(axis=0), atol=2e-3), shape.name
        assert np.allclose(drawn.max(axis=0), samples.max(axis=0), atol=2e-3), shape.name
    pose = np.zeros(POSE_WIDTH)
    shifted = pose.copy()
    shifted[:3] = [0.1, -0.2, 0.3]
    a, _ = hand_mesh_world(hand, pose)
    b, _ = hand_mesh_world(hand, shifted)
    assert np.allclose(b - a, [0.1, -0.2, 0.3], atol=1e-6)
    with pytest.raises(ValueError, match="hand_pose must be 15 finite numbers"):
        hand_mesh_world(hand, np.zeros(28))


def test_render_draws_the_stores_hand(tmp_path, tiny_objects, three_finger):
    import matplotlib.image

    from dexlite_pipeline.hand.choice import hand_record

    xml, _ = three_finger
    store = tmp_path / "g.zarr"
    write_grasp_store(store, GraspSet({"hand_pose": above_the_box(2), "object_id": np.array([OBJECT_ID] * 2, dtype=object),
                                       "scale": np.full(2, 0.06, np.float32)}), hand_record(str(xml)))  # fmt: skip
    assert type(hand_of_store(hand_record(str(xml)))).__name__ == "DescribedHand"
    out = tmp_path / "grasp.png"
    assert main(["render", str(store), "--objects", str(tiny_objects), "--index", "1", "--out", str(out), "--size-px", "200"]) == 0
    image = matplotlib.image.imread(out)
    assert image.shape[:2] == (200, 400)
    for half in (image[:, :200], image[:, 200:]):
        assert colour_fraction(half, HAND_RGB) > 0.005
        assert colour_fraction(half, OBJECT_RGB) > 0.01

    from dexlite_pipeline.io.grasp_store import read_grasp_store
    from dexlite_pipeline.report.grasp_view import write_grasp_set_view

    view = write_grasp_set_view(tmp_path / "view.html", read_grasp_store(store), [str(tiny_objects)])
    text = view.read_text()
    assert "hand, grasp 2" in text and "mesh3d" in text.lower()


def test_a_store_of_a_changed_hand_file_is_not_drawn(tmp_path, three_finger):
    from dexlite_pipeline.hand.choice import hand_record
    from dexlite_pipeline.report.render import RenderError

    xml, _ = three_finger
    record = {**hand_record(str(xml)), "hand_sha256": "0" * 64}
    with pytest.raises(RenderError, match="not the hand that file describes now"):
        hand_of_store(record)
