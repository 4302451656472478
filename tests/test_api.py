"""``dexlite_pipeline.api.grasp``: the same grasps as ``dexlite grasp`` for the same seed, in-memory meshes, one clear error."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import trimesh

from dexlite_pipeline.api import GraspToolError, grasp, palm_matrices_in_mesh_frame
from dexlite_pipeline.cli import main
from dexlite_pipeline.io.grasp_store import read_grasp_store

# A short optimization from scratch (as tests/tools/test_grasp.py): a few seconds per mesh.
TINY = {
    "objects": {"sdf_resolution": 24, "surface_points": 256, "coacd_mcts_iterations": 10, "coacd_mcts_nodes": 5, "coacd_mcts_max_depth": 1},
    "energy": {"object_point_spacing_m": 0.004},
    "optimize_grasps": {"annealing": {"iterations": 60}, "final_contact_samples": 32, "contact_search_every": 0},
}  # fmt: skip
README = Path(__file__).resolve().parents[1] / "README.md"


@pytest.mark.slow
def test_the_api_gives_the_grasps_of_the_command_for_the_same_seed(tmp_path):
    box = trimesh.creation.box((0.08, 0.06, 0.10))
    box.export(tmp_path / "box.obj")
    command_out = tmp_path / "command"
    main(["grasp", str(tmp_path / "box.obj"), "--out", str(command_out), "--n", "4", "--renders", "0", "--threads", "1",
          "--from-scratch", "--no-distinct", "--config-json", json.dumps({**TINY, "seed": 3})])  # fmt: skip
    by_command = read_grasp_store(command_out / "all_grasps.zarr")
    result = grasp([tmp_path / "box.obj"], n=4, seed=3, from_scratch=True, distinct=False, config=TINY, threads=1)
    grasps = result.meshes["user-box"]
    assert result.out_dir is None and grasps.attempts == 4
    held = np.asarray(by_command.arrays["lift_success"], bool)
    assert grasps.held == int(held.sum())
    kept = read_grasp_store(command_out / "grasps.zarr") if (command_out / "grasps.zarr").exists() else None
    np.testing.assert_array_equal(grasps.hand_pose, kept.hand_pose if kept is not None else np.zeros((0, 28), np.float32))
    # the same run in memory: the same grasps again
    in_memory = grasp({"box": box}, n=4, seed=3, from_scratch=True, distinct=False, config=TINY, threads=1)
    np.testing.assert_array_equal(in_memory.meshes["user-box"].hand_pose, grasps.hand_pose)
    assert grasps.failures == {k: v for k, v in grasps.failures.items() if v > 0} and sum(grasps.failures.values()) == 4 - grasps.held
    assert grasps.preparation["route"]["summary"].startswith("single shell")


def test_palm_matrices_are_in_the_mesh_files_frame_and_units():
    """A palm at object-frame position p maps to p / scale / normalization_factor + normalization_centre, rotation unchanged."""
    meta = {"normalization_factor": 1 / 50.0, "normalization_centre": [10.0, 0.0, -5.0]}  # a mesh in mm, radius ~50 mm
    pose = np.zeros((1, 28), np.float32)
    pose[0, :3] = [0.05, 0.0, 0.0]  # 5 cm from the centre, object frame in metres
    pose[0, 3:6] = [0.0, 0.0, np.pi / 2]
    scale = np.array([0.05], np.float32)  # metres per normalized unit: the object's radius is 5 cm
    matrix = palm_matrices_in_mesh_frame(pose, scale, meta)[0]
    np.testing.assert_allclose(matrix[:3, 3], [10.0 + 50.0, 0.0, -5.0], atol=1e-4)  # 50 mm along x from the centre
    np.testing.assert_allclose(matrix[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-6)


@pytest.mark.parametrize("meshes, message", [
    (["/no/such/mesh.obj"], "no such file or folder"),
    ([42], "expected a file path or a trimesh.Trimesh, got int"),
    ([], "no meshes given"),
])  # fmt: skip
def test_bad_input_raises_one_error_naming_the_problem(tmp_path, meshes, message):
    with pytest.raises(GraspToolError, match=message) as caught:
        grasp(meshes, n=1, from_scratch=True)
    assert "\n" not in str(caught.value)


def test_contradictory_options_are_refused_before_any_work(tmp_path):
    with pytest.raises(GraspToolError, match="--model and --from-scratch exclude each other"):
        grasp([tmp_path / "x.obj"], from_scratch=True, model="other.pt")


@pytest.mark.slow
def test_the_readme_python_example_runs_and_gives_the_commands_grasps(tmp_path, capsys):
    """The README's example, as written (the shipped model on an in-memory can), then ``dexlite grasp`` on the same can
    with the same seed: the same grasps."""
    text = README.read_text()
    section = text[text.index("## From Python"):text.index("## Install and test")]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    namespace = {}
    exec(compile(code, "README.md", "exec"), namespace)
    printed = capsys.readouterr().out
    assert re.search(r"\d+ of 8 held; \d+ distinct kept; failures:", printed), printed
    namespace["can"].export(tmp_path / "can.obj")
    main(["grasp", str(tmp_path / "can.obj"), "--out", str(tmp_path / "out"), "--n", "8", "--renders", "0", "--threads", "1",
          "--config-json", json.dumps({"seed": 0})])  # fmt: skip
    np.testing.assert_array_equal(read_grasp_store(tmp_path / "out" / "grasps.zarr").hand_pose, namespace["grasps"].hand_pose)
