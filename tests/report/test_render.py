"""Headless grasp pictures: both the hand and the object are visible, from two viewpoints."""

import numpy as np
import pytest
from image_colours import colour_fraction
from report_synthetic import OBJECT_ID, grasp_poses

from dexlite_pipeline.cli import main
from dexlite_pipeline.io.grasp_store import GraspSet, write_grasp_store
from dexlite_pipeline.report.render import HAND_RGB, OBJECT_RGB, hand_mesh_world, hand_visual




def test_hand_visual_mesh_follows_forward_kinematics(hand):
    visual = hand_visual()
    assert visual.faces.max() < len(visual.vertices) and len(visual.faces) > 1000
    pose = np.zeros(28)
    shifted = pose.copy()
    shifted[:3] = [0.1, -0.2, 0.3]
    a, _ = hand_mesh_world(hand, pose)
    b, _ = hand_mesh_world(hand, shifted)
    assert np.allclose(b - a, [0.1, -0.2, 0.3], atol=1e-6)


def test_render_cli_draws_hand_and_object(tmp_path, tiny_objects):
    import matplotlib.image

    store = tmp_path / "g.zarr"
    poses = grasp_poses(2, np.random.default_rng(0))
    write_grasp_store(store, GraspSet({"hand_pose": poses, "object_id": np.array([OBJECT_ID] * 2, dtype=object), "scale": np.full(2, 0.06, np.float32)}))
    out = tmp_path / "grasp.png"
    assert main(["render", str(store), "--objects", str(tiny_objects), "--index", "1", "--out", str(out), "--size-px", "200"]) == 0
    image = matplotlib.image.imread(out)
    assert image.shape[0] == 200 and image.shape[1] == 400  # two views side by side
    for half in (image[:, :200], image[:, 200:]):
        assert colour_fraction(half, HAND_RGB) > 0.01
        assert colour_fraction(half, OBJECT_RGB) > 0.01
    assert main(["render", str(store), "--objects", str(tiny_objects), "--index", "5", "--out", str(out)]) == 2


def test_render_rejects_bad_pose(hand):
    from dexlite_pipeline.report.render import RenderError

    with pytest.raises(RenderError):
        hand_mesh_world(hand, np.full(28, np.nan))


def test_render_cli_names_the_file_and_row_of_a_nan_pose(tmp_path, tiny_objects, capsys):
    store = tmp_path / "g.zarr"
    poses = grasp_poses(2, np.random.default_rng(0))
    poses[1, 4] = np.nan
    write_grasp_store(store, GraspSet({"hand_pose": poses, "object_id": np.array([OBJECT_ID] * 2, dtype=object), "scale": np.full(2, 0.06, np.float32)}))
    out = tmp_path / "grasp.png"
    assert main(["render", str(store), "--objects", str(tiny_objects), "--index", "1", "--out", str(out)]) == 2
    error = capsys.readouterr().err.strip()
    assert error == f"dexlite render: error: {store}: row 1 ({OBJECT_ID}): hand_pose is not finite at position(s) 4"
    assert not out.exists()


def test_render_finds_the_objects_beside_a_grasp_output_folders_store(tmp_path, tiny_objects):
    """In a `dexlite grasp` output folder (DIR/grasps.zarr beside DIR/objects) --objects is not needed."""
    import shutil

    run = tmp_path / "run"
    shutil.copytree(tiny_objects, run / "objects")
    poses = grasp_poses(1, np.random.default_rng(0))
    write_grasp_store(run / "grasps.zarr", GraspSet({"hand_pose": poses, "object_id": np.array([OBJECT_ID], dtype=object), "scale": np.full(1, 0.06, np.float32)}))
    assert main(["render", str(run / "grasps.zarr"), "--out", str(tmp_path / "g.png"), "--size-px", "100"]) == 0
    assert (tmp_path / "g.png").read_bytes()[:4] == b"\x89PNG"


def test_table_square_lies_in_the_table_plane_under_the_object():
    from dexlite_pipeline.report.render import table_square

    normal = np.array([0.1, -0.2, 1.0])
    unit = normal / np.linalg.norm(normal)
    centre = np.array([0.01, 0.02, 0.03])
    square = table_square(normal, 0.05, centre, 0.1)
    assert square.shape == (4, 3)
    assert np.allclose(square @ unit + 0.05, 0.0, atol=1e-12)  # every corner on the plane n.x + offset = 0
    foot = square.mean(axis=0)
    assert np.allclose(np.cross(centre - foot, unit), 0.0, atol=1e-12)  # centred right under (or over) the object
    assert np.allclose(np.linalg.norm(square - foot, axis=1), 0.1 * np.sqrt(2))


def test_a_grasp_on_a_table_is_pictured_with_it(tmp_path):
    """The table's colour appears in the picture of a grasp that records a table, and not in one that does not."""
    import io as _io

    import matplotlib.image as mpimg

    from dexlite_pipeline.report.render import TABLE_RGBA, grasp_table
    from dexlite_pipeline.io.grasp_store import GraspSet

    pose = np.zeros((1, 28), np.float32)
    pose[0, :3] = (0.0, -0.12, 0.0)
    floating = GraspSet({"hand_pose": pose, "object_id": np.array(["o"], dtype=object), "scale": np.array([0.1], np.float32)})
    on_table = GraspSet({**floating.arrays, "support_normal": np.array([[0.0, 0.0, 1.0]], np.float32),
                         "support_offset_m": np.array([0.1], np.float32)})
    assert grasp_table(floating, 0) is None and grasp_table(on_table, 0)[1] == pytest.approx(0.1)

    def table_pixels(table) -> int:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import trimesh

        from dexlite_pipeline.report.render import draw_grasp

        box = trimesh.creation.box(extents=(0.1, 0.1, 0.2))
        object_mesh = (np.asarray(box.vertices), np.asarray(box.faces))
        far_hand = (np.asarray(box.vertices) + 5.0, np.asarray(box.faces))  # out of the frame
        fig = plt.figure(figsize=(3, 3), dpi=100)
        ax = fig.add_subplot(projection="3d")
        draw_grasp(ax, far_hand, object_mesh, 20.0, 30.0, table)
        buffer = _io.BytesIO()
        fig.savefig(buffer, format="png")
        plt.close(fig)
        image = mpimg.imread(_io.BytesIO(buffer.getvalue()))[..., :3]
        # the translucent table over the white background: the table colour blended at its alpha
        expected = np.array(TABLE_RGBA[:3]) * TABLE_RGBA[3] + (1 - TABLE_RGBA[3])
        return int((np.abs(image - expected).max(axis=-1) < 0.03).sum())

    assert table_pixels(grasp_table(on_table, 0)) > 500
    assert table_pixels(None) == 0
