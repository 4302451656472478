"""``dexlite grasp``: from mesh files made here to held grasps, stores, export, pictures and a summary."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import trimesh

from dexlite_pipeline.cli import main
from dexlite_pipeline.io.grasp_store import read_grasp_store

# Small grids, a light CoACD search and a short optimization: a budget for tests, not for use.
TINY = {
    "objects": {"sdf_resolution": 32, "surface_points": 512, "coacd_mcts_iterations": 10, "coacd_mcts_nodes": 5,
                "coacd_mcts_max_depth": 1, "coacd_resolution": 300},
    "energy": {"object_points": 300},
    "seed_grasps": {"annealing": {"iterations": 60}, "final_contact_samples": 32, "contact_search_every": 0},
    "post_optimize": {"annealing": {"iterations": 5}, "energy_object_points": 300, "start_contact_samples": 8, "final_contact_samples": 8},
}  # fmt: skip


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    """An 8 x 6 x 10 cm box (.obj) and an open-bottomed cylinder of 7 cm diameter (.stl), in metres."""
    folder = tmp_path_factory.mktemp("meshes")
    trimesh.creation.box((0.08, 0.06, 0.10)).export(folder / "box.obj")
    cylinder = trimesh.creation.cylinder(radius=0.035, height=0.09, sections=32)
    bottom = cylinder.face_normals[:, 2] < -0.99
    trimesh.Trimesh(cylinder.vertices, cylinder.faces[~bottom], process=False).export(folder / "cup.stl")
    return folder


@pytest.fixture(scope="module")
def grasp_run(meshes, tmp_path_factory):
    out = tmp_path_factory.mktemp("grasp") / "out"
    code = main(["grasp", str(meshes), "--out", str(out), "--n", "2", "--real-size", "--renders", "1", "--threads", "2",
                 "--from-scratch", "--config-json", json.dumps(TINY)])  # fmt: skip
    return code, out


@pytest.mark.slow
def test_grasp_writes_every_output_for_an_obj_and_an_stl(grasp_run):
    code, out = grasp_run
    every = read_grasp_store(out / "all_grasps.zarr")
    held = read_grasp_store(out / "grasps.zarr")
    assert sorted(set(every.object_id)) == ["user-box", "user-cup"]
    assert [int((every.object_id == o).sum()) for o in ("user-box", "user-cup")] == [2, 2]
    lifted = np.asarray(every.arrays["lift_success"], bool)
    assert len(held) == int(lifted.sum())
    assert code == (0 if len(held) else 1)
    for name in ("hand_pose", "object_id", "scale", "lift_success", "failure_reason", "six_dir_success", "six_dir_passed", "E_fc", "E_pen"):
        assert name in held.arrays and name in every.arrays
    assert held.hand_pose.shape[1:] == (28,)
    for object_id in set(held.object_id):
        assert (out / "dexgraspnet" / "dataset" / f"{object_id}.npy").is_file()
        assert (out / "dexgraspnet" / "meshdata" / object_id / "coacd" / "decomposed.obj").is_file()
    renders = sorted(p.name for p in (out / "renders").glob("*.png"))
    assert [name.split("_")[0] for name in renders] == ["user-box", "user-cup"]
    summary = (out / "summary.md").read_text()
    assert "| user-box | box.obj |" in summary and "| user-cup | cup.stl |" in summary
    assert f"{int(lifted.sum())}/4 (" in summary and "six-direction" in summary
    for name in renders:
        assert f"renders/{name}" in summary


@pytest.mark.slow
def test_real_size_keeps_the_mesh_units_as_metres(grasp_run):
    _, out = grasp_run
    every = read_grasp_store(out / "all_grasps.zarr")
    # Normalized objects have radius 1 / 1.03, so the scale that restores the box is 1.03 x its half-diagonal.
    box = every.scale[every.object_id == "user-box"]
    assert np.allclose(box, 1.03 * np.linalg.norm([0.04, 0.03, 0.05]), rtol=1e-5)
    cup = every.scale[every.object_id == "user-cup"]
    assert np.allclose(cup, 1.03 * np.hypot(0.035, 0.045), rtol=1e-3)


@pytest.mark.slow
def test_grasp_with_a_model_samples_and_post_optimizes(grasp_run, meshes, tmp_path):
    """A trained model's path (here untrained weights: the test is of the plumbing, not the grasps)."""
    from dexlite_pipeline.model.checkpoint import save_checkpoint
    from dexlite_pipeline.model.config import ModelConfig
    from dexlite_pipeline.model.network import GraspCVAE

    @dataclasses.dataclass
    class Trained:
        points_per_cloud: int = 64

    model = tmp_path / "cvae.pt"
    small = ModelConfig(pointnet_widths=(16, 32), encoder_hidden=(32,), decoder_hidden=(32,), latent_dim=8, normalization="none")
    save_checkpoint(model, GraspCVAE(small), Trained(), {"seed": 0})
    out = tmp_path / "with_model"
    code = main(["grasp", str(meshes / "box.obj"), "--out", str(out), "--n", "3", "--renders", "0", "--threads", "1",
                 "--model", str(model), "--config-json", json.dumps(TINY)])  # fmt: skip
    every = read_grasp_store(out / "all_grasps.zarr")
    assert len(every) == 3 and set(every.arrays["method"]) == {"cvae_post"}
    assert "raw_hand_pose" in every.arrays and np.isfinite(every.hand_pose).all()
    assert sorted(set(np.round(every.scale, 3))) == [0.08, 0.1, 0.12]
    assert code == (0 if every.arrays["lift_success"].any() else 1)


@pytest.mark.slow
def test_grasp_uses_the_shipped_model_when_no_model_is_given(meshes, tmp_path, monkeypatch):
    """Without --model (and without --from-scratch) the checkout's shipped model samples the grasps."""
    from dexlite_pipeline.model import shipped
    from dexlite_pipeline.model.checkpoint import save_checkpoint
    from dexlite_pipeline.model.config import ModelConfig
    from dexlite_pipeline.model.network import GraspCVAE

    @dataclasses.dataclass
    class Trained:
        points_per_cloud: int = 64

    stand_in = tmp_path / "models" / "cvae.pt"
    stand_in.parent.mkdir()
    small = ModelConfig(pointnet_widths=(16, 32), encoder_hidden=(32,), decoder_hidden=(32,), latent_dim=8, normalization="none")
    save_checkpoint(stand_in, GraspCVAE(small), Trained(), {"seed": 0})
    monkeypatch.setattr(shipped, "SHIPPED_MODEL_PATH", stand_in)
    out = tmp_path / "shipped"
    main(["grasp", str(meshes / "box.obj"), "--out", str(out), "--n", "1", "--renders", "0", "--threads", "1", "--config-json", json.dumps(TINY)])
    assert set(read_grasp_store(out / "all_grasps.zarr").arrays["method"]) == {"cvae_post"}
    assert f"model: {stand_in}" in (out / "summary.md").read_text()
    assert main(["grasp", str(meshes / "box.obj"), "--out", str(out), "--model", str(stand_in), "--from-scratch"]) == 2


def test_grasp_input_errors_are_one_line_with_exit_status_2(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("not a mesh")
    empty = tmp_path / "empty"
    empty.mkdir()
    for target, message in (
        (tmp_path / "missing.obj", "no such file or folder"),
        (tmp_path / "notes.txt", "not a mesh file"),
        (empty, "folder has no .obj/.stl files"),
    ):
        assert main(["grasp", str(target), "--out", str(tmp_path / "out")]) == 2
        error = capsys.readouterr().err.strip()
        assert error == f"dexlite grasp: error: {target}: {message}" + (" (expected .obj or .stl)" if "mesh file" in message else "")
    assert main(["grasp", str(tmp_path / "notes.txt"), "--out", str(tmp_path / "out"), "--config-json", '{"lift": {"friction": "high"}}']) == 2
    assert 'lift.friction: expected a number, got a string "high"' in capsys.readouterr().err


def test_grasp_fails_when_no_mesh_can_be_prepared(tmp_path, capsys):
    flat = tmp_path / "flat.obj"
    flat.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n")
    assert main(["grasp", str(flat), "--out", str(tmp_path / "out"), "--threads", "1", "--config-json", json.dumps(TINY)]) == 2
    error = capsys.readouterr().err.strip()
    assert error.startswith("dexlite grasp: error: none of the 1 mesh(es) could be prepared:") and "flat.obj: degenerate: flat" in error
