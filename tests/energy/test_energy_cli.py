"""`dexlite energy` on a small store: every term added, the input arrays kept, a bad object reported."""

from __future__ import annotations

import numpy as np

from dexlite_pipeline.cli import main
from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store, write_grasp_store


def test_energy_cli_adds_terms(sphere_objects, tmp_path, capsys):
    pose = np.zeros((3, 28), np.float32)
    pose[:, 2] = [-0.05, -0.3, -0.05]  # palm through the sphere, far below it, unknown object
    grasps = GraspSet({"hand_pose": pose, "object_id": np.array(["sphere", "sphere", "ghost"], dtype=object),
                       "scale": np.full(3, 0.08, np.float32), "lift_ratio": np.arange(3, dtype=np.float32)})
    write_grasp_store(tmp_path / "in.zarr", grasps)
    code = main(["energy", str(tmp_path / "in.zarr"), "--objects", str(sphere_objects), "--out", str(tmp_path / "out.zarr"), "--threads", "1"])
    assert code == 0
    out = read_grasp_store(tmp_path / "out.zarr")
    assert np.array_equal(out.arrays["lift_ratio"], grasps.arrays["lift_ratio"])
    assert out.arrays["penetration_mm"][0] > 10 and out.arrays["penetration_mm"][1] == 0
    assert out.arrays["E_pen"][0] > 0 and out.arrays["E_pen"][1] == 0
    assert np.isnan(out.arrays["E_fc"][2]) and "ghost" in out.arrays["energy_failure_reason"][2]
    assert not out.arrays["passes_energy_thresholds"].any()
    assert out.attrs["energy"]["config"]["weights"]["pen"] == 100.0
    printed = capsys.readouterr().out
    assert "grasps: 3, evaluated: 2" in printed and "penetration_mm" in printed


def test_energy_cli_flags_invalid_rows_and_fills_missing_contacts(sphere_objects, tmp_path):
    pose = np.zeros((3, 28), np.float32)
    pose[:, 2] = -0.05
    pose[1, 0] = np.nan
    contacts = np.array([[0, 1, 2, 3], [0, 1, 2, 3], [-1, -1, -1, -1]], np.int64)
    grasps = GraspSet({"hand_pose": pose, "object_id": np.array(["sphere"] * 3, dtype=object),
                       "scale": np.full(3, 0.08, np.float32), "contact_index": contacts})
    write_grasp_store(tmp_path / "in.zarr", grasps)
    assert main(["energy", str(tmp_path / "in.zarr"), "--objects", str(sphere_objects), "--out", str(tmp_path / "out.zarr"), "--threads", "1"]) == 0
    out = read_grasp_store(tmp_path / "out.zarr").arrays
    assert list(out["energy_failure_reason"]) == ["", "non-finite hand_pose", ""]
    assert np.isnan(out["E_fc"][1]) and np.isfinite(out["E_fc"][[0, 2]]).all()
    np.testing.assert_array_equal(out["contact_index"][0], [0, 1, 2, 3])  # given contacts are kept
    assert (out["contact_index"][2] >= 0).all()  # a row of -1 gets the contacts the pose makes, not candidate -1


def test_energy_cli_missing_store_is_an_error(sphere_objects, tmp_path, capsys):
    code = main(["energy", str(tmp_path / "nope.zarr"), "--objects", str(sphere_objects), "--out", str(tmp_path / "o.zarr")])
    assert code == 2 and "nope.zarr" in capsys.readouterr().err


def test_energy_cli_takes_its_weights_from_config_json(sphere_objects, tmp_path):
    """--config-json, as for the other commands: inline JSON or a file such as config.yaml."""
    pose = np.zeros((1, 28), np.float32)
    pose[:, 2] = -0.05
    write_grasp_store(tmp_path / "in.zarr", GraspSet({"hand_pose": pose, "object_id": np.array(["sphere"], dtype=object), "scale": np.full(1, 0.08, np.float32)}))
    args = ["energy", str(tmp_path / "in.zarr"), "--objects", str(sphere_objects), "--out", str(tmp_path / "out.zarr"), "--threads", "1"]
    assert main([*args, "--config-json", '{"energy": {"weights": {"pen": 50.0}}}']) == 0
    assert read_grasp_store(tmp_path / "out.zarr").attrs["energy"]["config"]["weights"]["pen"] == 50.0
    (tmp_path / "c.yaml").write_text("energy:\n  weights:\n    pen: 25.0\n")
    assert main([*args, "--config-json", str(tmp_path / "c.yaml")]) == 0
    assert read_grasp_store(tmp_path / "out.zarr").attrs["energy"]["config"]["weights"]["pen"] == 25.0
    assert main([*args, "--config-json", '{"energy": {"wieghts": {}}}']) == 2  # a misspelled key is refused
