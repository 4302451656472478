"""``dexlite lift-test`` and the ``lift_validate`` stage: outputs, flags, summaries, one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import zarr
from bar_grasps import grasp_set

from dexlite_pipeline.cli import main
from dexlite_pipeline.io.grasp_store import read_grasp_store, write_grasp_store


def _store_with_bad_rows(tmp_path, hooks):
    """Four grasps: good, NaN pose, object missing from the assets, good again (other bar)."""
    nan_pose = hooks["square_bar"].copy()
    nan_pose[0] = np.nan
    grasps = grasp_set(
        [hooks["square_bar"], nan_pose, hooks["square_bar"], hooks["round_bar"]],
        ["square_bar", "square_bar", "mug_that_was_never_prepared", "round_bar"],
    )
    grasps.arrays["E_fc"] = np.arange(4, dtype=np.float32)  # an upstream column travels along
    path = tmp_path / "grasps.zarr"
    write_grasp_store(path, grasps, {"stage": "curate"})
    return path


def test_lift_test_flags_bad_rows_simulates_the_rest_and_prints_a_summary(tmp_path, objects_dir, hooks, capsys, caplog):
    source = _store_with_bad_rows(tmp_path, hooks)
    out = tmp_path / "lifted.zarr"
    code = main(["lift-test", str(source), "--objects", str(objects_dir), "--out", str(out), "--friction", "0.8", "--threads", "1"])
    assert code == 0
    result = read_grasp_store(out)
    assert result.arrays["failure_reason"].tolist() == [
        "",
        "invalid_grasp: non-finite hand_pose",
        "invalid_grasp: object id not in the object assets",
        "",
    ]
    assert result.arrays["lift_success"].tolist() == [True, False, False, True]
    np.testing.assert_array_equal(result.arrays["E_fc"], np.arange(4))
    assert result.attrs["lift_config"]["friction"] == 0.8
    assert result.attrs["lift_summary"]["n_success"] == 2 and result.attrs["lift_summary"]["n_simulated"] == 2
    printed = capsys.readouterr()
    assert "2/4 grasps lifted (50.0%)" in printed.out
    assert "invalid_grasp: non-finite hand_pose: 1" in printed.out
    assert "friction 0.8" in printed.out
    assert "1 grasp(s) not simulated: invalid_grasp: object id not in the object assets" in caplog.text


def test_lift_test_six_directions_option_stores_per_direction_results(tmp_path, objects_dir, hooks):
    source = tmp_path / "one.zarr"
    write_grasp_store(source, grasp_set([hooks["square_bar"]], ["square_bar"]))
    out = tmp_path / "six.zarr"
    assert main(["lift-test", str(source), "--objects", str(objects_dir), "--out", str(out), "--six-directions", "--threads", "1"]) == 0
    result = read_grasp_store(out)
    assert result.arrays["six_dir_passed"].shape == (1, 6)
    assert result.arrays["six_dir_rotation_deg"].shape == (1, 6)
    assert result.attrs["six_dir_directions"] == ["+x", "-x", "+y", "-y", "+z", "-z"]
    assert result.attrs["lift_config"]["six_directions"] is True


def test_lift_test_one_line_errors(tmp_path, objects_dir, capsys):
    bad = tmp_path / "bad.zarr"
    group = zarr.open_group(str(bad), mode="w", zarr_format=3)
    group.create_array("hand_pose", data=np.zeros((3, 27), np.float32))
    group.create_array("object_id", shape=(3,), dtype=str)[:] = np.array(["a", "b", "c"], dtype=object)
    group.create_array("scale", data=np.full(3, 0.1, np.float32))
    out = tmp_path / "never.zarr"
    assert main(["lift-test", str(bad), "--objects", str(objects_dir), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"dexlite lift-test: error: {bad}: hand_pose has shape (3, 27), expected (N, 28) for hand shadow"]
    assert not out.exists()

    assert main(["lift-test", str(tmp_path / "missing.zarr"), "--objects", str(objects_dir), "--out", str(out)]) == 2
    assert "no such grasp store" in capsys.readouterr().err
    assert main(["lift-test", str(bad), "--objects", str(tmp_path / "no_objects"), "--out", str(out)]) == 2
    assert "objects folder not found" in capsys.readouterr().err
    assert main(["lift-test", str(bad), "--objects", str(objects_dir), "--out", str(out), "--config-json", '{"lift": {"fricton": 1}}']) == 2
    assert "unknown key(s) fricton" in capsys.readouterr().err


def test_lift_validate_stage_writes_the_shard_with_its_config(tmp_path, objects_dir, hooks):
    source = _store_with_bad_rows(tmp_path, hooks)
    out = tmp_path / "lift" / "shard_000.zarr"
    config = {"seed": 3, "device": "cpu", "lift": {"friction": 1.0, "six_directions": False}, "scene": {"table": False}}
    code = main(["lift-validate", "--config-json", json.dumps(config), "--grasps", str(source), "--objects", str(objects_dir),
                 "--shard", "000", "--out", str(out), "--threads", "1"])
    assert code == 0
    result = read_grasp_store(out)
    assert len(result) == 4  # every curated grasp is kept, failures with their reason
    assert result.arrays["lift_success"].tolist() == [True, False, False, True]
    assert result.attrs["stage"] == "lift_validate" and result.attrs["shard"] == "000"
    assert result.attrs["config"]["lift"]["friction"] == 1.0 and result.attrs["config"]["seed"] == 3
    assert "six_dir_success" not in result.arrays


def test_lift_validate_on_tables_records_the_support_plane_and_rejects_hands_in_the_table(tmp_path, objects_dir, hooks):
    """Tabletop mode (the default): resting poses from the stability table; the hook under the lying square bar
    is in its table, the hook of the standing one holds; both record their plane; no table: a one-line error."""
    import pandas as pd

    stability = tmp_path / "stability.parquet"
    pd.DataFrame({"object_id": ["square_bar", "round_bar"], "stable": [True, True], "support_nx": [1.0, 0.0], "support_ny": 0.0,
                  "support_nz": [0.0, 1.0], "support_offset": [1.0, 0.25]}).to_parquet(stability)
    source = tmp_path / "curated.zarr"
    write_grasp_store(source, grasp_set([hooks["square_bar"], hooks["round_bar"]], ["square_bar", "round_bar"]))
    out = tmp_path / "lift.zarr"
    args = ["lift-validate", "--config-json", json.dumps({"seed": 3}), "--grasps", str(source), "--objects", str(objects_dir),
            "--shard", "000", "--out", str(out), "--threads", "1"]
    assert main([*args, "--stability", str(stability)]) == 0
    result = read_grasp_store(out)
    assert result.arrays["failure_reason"].tolist() == ["", "hand_in_table"]
    assert result.arrays["lift_success"].tolist() == [True, False]
    np.testing.assert_allclose(result.arrays["support_normal"], [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(result.arrays["support_offset_m"], [0.08, 0.02], rtol=1e-6)
    assert result.attrs["scene"] == {"table": True} and result.attrs["config"]["scene"] == {"table": True}
    assert main(args) == 2  # tabletop mode without the resting poses


def test_lift_test_reproduces_a_grasp_on_the_table_its_store_recorded(tmp_path, objects_dir, hooks, capsys):
    """A store written on tables carries each grasp's plane: `dexlite lift-test` puts the objects back on them and
    says so; --floating tests without them (the hook under the lying round bar then holds)."""
    from dexlite_pipeline.tabletop import store_arrays

    grasps = grasp_set([hooks["square_bar"], hooks["round_bar"]], ["square_bar", "round_bar"])
    grasps.arrays.update(store_arrays(np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), np.array([0.08, 0.02])))
    source = tmp_path / "on_tables.zarr"
    write_grasp_store(source, grasps)
    assert main(["lift-test", str(source), "--objects", str(objects_dir), "--out", str(tmp_path / "t.zarr"), "--threads", "1"]) == 0
    assert "on the tables recorded in the grasp store" in capsys.readouterr().out
    assert read_grasp_store(tmp_path / "t.zarr").arrays["failure_reason"].tolist() == ["", "hand_in_table"]
    assert main(["lift-test", str(source), "--objects", str(objects_dir), "--out", str(tmp_path / "f.zarr"), "--threads", "1", "--floating"]) == 0
    assert "floating (--floating)" in capsys.readouterr().out
    assert read_grasp_store(tmp_path / "f.zarr").arrays["lift_success"].tolist() == [True, True]


def test_lift_test_on_an_objects_folder_without_objects_fails(tmp_path, hooks, capsys):
    source = tmp_path / "one.zarr"
    write_grasp_store(source, grasp_set([hooks["square_bar"]], ["square_bar"]))
    empty = tmp_path / "empty_objects"
    empty.mkdir()
    assert main(["lift-test", str(source), "--objects", str(empty), "--out", str(tmp_path / "out.zarr")]) == 2
    err = capsys.readouterr().err
    assert str(empty) in err and "no prepared objects" in err
    assert not (tmp_path / "out.zarr").exists()


def test_lift_test_with_no_simulable_grasp_exits_non_zero(tmp_path, objects_dir, hooks, caplog):
    source = tmp_path / "unknown.zarr"
    write_grasp_store(source, grasp_set([hooks["square_bar"]] * 2, ["never_prepared"] * 2))
    assert main(["lift-test", str(source), "--objects", str(objects_dir), "--out", str(tmp_path / "out.zarr"), "--threads", "1"]) == 1
    assert "none of the 2 grasps could be simulated" in caplog.text


def test_lift_test_log_has_progress_lines(tmp_path, objects_dir, hooks):
    """The command as a job runs it: a separate process whose standard error is the log file."""
    source = tmp_path / "two.zarr"
    write_grasp_store(source, grasp_set([hooks["square_bar"], hooks["round_bar"]], ["square_bar", "round_bar"]))
    log = tmp_path / "lift.log"
    with open(log, "w") as stream:
        code = subprocess.run(
            [sys.executable, "-m", "dexlite_pipeline.cli", "lift-test", str(source), "--objects", str(objects_dir),
             "--out", str(tmp_path / "out.zarr"), "--threads", "1"],
            stdout=stream, stderr=subprocess.STDOUT, check=False,
        ).returncode  # fmt: skip
    text = log.read_text()
    assert code == 0, text
    progress = [line for line in text.splitlines() if "lift test: " in line and "grasps/s" in line]
    assert progress and "2/2 grasps (100%)" in progress[-1], text


def test_config_errors_name_the_key_and_the_expected_type(tmp_path, objects_dir, hooks, capsys):
    source = tmp_path / "one.zarr"
    write_grasp_store(source, grasp_set([hooks["square_bar"]], ["square_bar"]))
    run = ["lift-test", str(source), "--objects", str(objects_dir), "--out", str(tmp_path / "out.zarr"), "--threads", "1"]
    assert main([*run, "--config-json", '{"lift": {"friction": "abc"}}']) == 2
    assert capsys.readouterr().err.strip() == 'dexlite lift-test: error: --config-json: lift.friction: expected a number, got a string "abc"'
    assert main([*run, "--config-json", str(tmp_path / "my.json")]) == 2
    assert f"--config-json {tmp_path / 'my.json'}: no such file" in capsys.readouterr().err
    assert not (tmp_path / "out.zarr").exists()


def test_config_json_accepts_a_json_or_yaml_file(tmp_path, objects_dir, hooks, capsys):
    source = tmp_path / "one.zarr"
    write_grasp_store(source, grasp_set([hooks["square_bar"]], ["square_bar"]))
    (tmp_path / "my.json").write_text('{"lift": {"friction": 0.9}}')
    (tmp_path / "my.yaml").write_text("lift:\n  friction: 0.7\n  object_mass_kg: 0.2\n")
    for name, friction in (("my.json", 0.9), ("my.yaml", 0.7)):
        out = tmp_path / f"{name}.zarr"
        assert main(["lift-test", str(source), "--objects", str(objects_dir), "--out", str(out), "--threads", "1", "--config-json", str(tmp_path / name)]) == 0
        assert read_grasp_store(out).attrs["lift_config"]["friction"] == friction
    (tmp_path / "bad.yaml").write_text("lift:\n  friction: [1, 2]\n")
    assert main(["lift-test", str(source), "--objects", str(objects_dir), "--out", str(tmp_path / "x.zarr"), "--config-json", str(tmp_path / "bad.yaml")]) == 2
    assert f"--config-json {tmp_path / 'bad.yaml'}: lift.friction: expected a number, got a list [1, 2]" in capsys.readouterr().err


def test_an_unwritable_output_is_named_as_the_user_gave_it(tmp_path, objects_dir, hooks, capsys):
    source = tmp_path / "one.zarr"
    write_grasp_store(source, grasp_set([hooks["square_bar"]], ["square_bar"]))
    out = "/proc/dexlite_lifted.zarr"  # not writable, even for root
    assert main(["lift-test", str(source), "--objects", str(objects_dir), "--out", out, "--threads", "1"]) == 2
    err = capsys.readouterr().err
    assert f"error: {out}" in err and ".tmp-" not in err, err
