"""The optimize_grasps stage end to end on two tiny objects: output schema, thresholds flag, determinism."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pandas as pd
import pytest

from dexlite_pipeline.cli import main
from dexlite_pipeline.io.grasp_store import read_grasp_store
from dexlite_pipeline.energy.config import EnergyThresholds

CONFIG = {
    "seed": 3,
    "device": "cpu",
    "shards": 1,
    "energy": {"object_point_spacing_m": 0.004},
    "optimize_grasps": {
        "grasps_per_object": 3,
        "scales": [0.08, 0.1],
        "batch_size": 8,
        "progress_every": 5,
        "init": {"distance_m": [0.05, 0.08]},
        "annealing": {"iterations": 10}, "trace_every": 5,
    },
}


# Resting poses: the box (extents 1.2 x 0.8 x 0.6, centred) lies flat, its table 0.3 below its origin per unit scale.
BOTH_REST = {"support_nx": [0.0, 0.0], "support_ny": [0.0, 0.0], "support_nz": [1.0, 1.0], "support_offset": [1.0, 0.3]}
REST_POSES = {"support_nx": [np.nan, 0.0], "support_ny": [np.nan, 0.0], "support_nz": [np.nan, 1.0], "support_offset": [np.nan, 0.3]}


@pytest.fixture(scope="module")
def stability(optim_objects, tmp_path_factory):
    path = tmp_path_factory.mktemp("stability") / "stability.parquet"
    pd.DataFrame({"object_id": ["sphere", "box"], "stable": [False, True], "reason": ["rolls", ""], **REST_POSES}).to_parquet(path)
    return path


def _run(objects, stability, out, config=CONFIG) -> int:
    return main(["optimize-grasps", "--config-json", json.dumps(config), "--shard", "000", "--stability", str(stability),
                 "--objects", str(objects), "--out", str(out), "--threads", "1"])


def test_optimize_stage_writes_every_term_and_is_deterministic(optim_objects, stability, tmp_path, caplog):
    caplog.set_level("INFO")
    assert _run(optim_objects, stability, tmp_path / "a.zarr") == 0
    grasps = read_grasp_store(tmp_path / "a.zarr")
    assert len(grasps) == 6  # only the stable box: 3 grasps x 2 scales
    assert set(grasps.object_id) == {"box"}
    assert sorted(set(grasps.scale.tolist())) == pytest.approx([0.08, 0.1])
    for name in ("E_fc", "E_dis", "E_pen", "E_spen", "E_joints", "E_total", "penetration_mm", "contact_distance_mm"):
        assert grasps.arrays[name].shape == (6,) and np.isfinite(grasps.arrays[name]).all()
    flag = grasps.arrays["passes_energy_thresholds"]
    assert np.array_equal(flag, EnergyThresholds().passes(grasps.arrays))
    attrs = grasps.attrs
    assert attrs["seconds_per_grasp"] > 0 and attrs["objects"] == ["box"]
    assert attrs["config"]["optimize_grasps"]["annealing"]["iterations"] == 10
    assert any("iteration 5/10" in r.getMessage() for r in caplog.records)

    assert _run(optim_objects, stability, tmp_path / "b.zarr") == 0
    again = read_grasp_store(tmp_path / "b.zarr")
    assert np.array_equal(again.hand_pose, grasps.hand_pose)
    assert np.array_equal(again.arrays["contact_index"], grasps.arrays["contact_index"])


def test_optimize_stage_missing_stability_table_is_a_clear_error(optim_objects, tmp_path, capsys):
    assert _run(optim_objects, tmp_path / "none.parquet", tmp_path / "c.zarr") == 2
    assert "none.parquet" in capsys.readouterr().err
    assert not (tmp_path / "c.zarr").exists()


def test_shard_without_stable_objects_writes_the_full_schema(optim_objects, stability, tmp_path):
    """Curation keeps only arrays every input has: an empty shard must not lack the energy arrays."""
    nothing_stable = tmp_path / "nothing_stable.parquet"
    pd.DataFrame({"object_id": ["sphere", "box"], "stable": [False, False], **REST_POSES}).to_parquet(nothing_stable)
    assert _run(optim_objects, nothing_stable, tmp_path / "empty.zarr") == 0
    assert _run(optim_objects, stability, tmp_path / "full.zarr") == 0
    empty, full = read_grasp_store(tmp_path / "empty.zarr"), read_grasp_store(tmp_path / "full.zarr")
    assert len(empty) == 0 and len(full) == 6
    assert {k: (v.dtype, v.shape[1:]) for k, v in empty.arrays.items()} == {k: (v.dtype, v.shape[1:]) for k, v in full.arrays.items()}


def test_damaged_asset_is_recorded_and_the_other_objects_synthesized(optim_objects, tmp_path):
    objects = tmp_path / "objects"
    shutil.copytree(optim_objects, objects)
    for chunk in (objects / "assets" / "box" / "arrays.zarr" / "sdf" / "c").rglob("*"):
        if chunk.is_file():
            chunk.write_bytes(b"not zstd")  # zarr's codec raises RuntimeError
    both_stable = tmp_path / "both_stable.parquet"
    pd.DataFrame({"object_id": ["sphere", "box"], "stable": [True, True], **BOTH_REST}).to_parquet(both_stable)
    assert _run(objects, both_stable, tmp_path / "out.zarr") == 0
    grasps = read_grasp_store(tmp_path / "out.zarr")
    assert set(grasps.object_id) == {"sphere"}
    assert list(grasps.attrs["failed_objects"]) == ["box"] and "arrays.zarr" in grasps.attrs["failed_objects"]["box"]


def test_optimize_stage_catalog_without_status_column_is_a_clear_error(optim_objects, stability, tmp_path, capsys):
    objects = tmp_path / "objects"
    shutil.copytree(optim_objects, objects)
    pd.read_parquet(objects / "catalog.parquet").drop(columns="status").to_parquet(objects / "catalog.parquet")
    assert _run(objects, stability, tmp_path / "d.zarr") == 2
    error = capsys.readouterr().err
    assert "catalog.parquet" in error and "status" in error and len(error.strip().splitlines()) == 1


def test_tabletop_optimized_grasps_start_above_the_table_and_record_it(optim_objects, stability, tmp_path):
    """Tabletop mode (the default): every start's palm is above the box's table, E_table is in the
    energy and stored, and each grasp records its support plane; the store records the mode."""
    from dexlite_pipeline.energy.table_clearance import HandTableClearance

    assert _run(optim_objects, stability, tmp_path / "t.zarr") == 0
    grasps = read_grasp_store(tmp_path / "t.zarr")
    assert grasps.attrs["scene"] == {"table": True}
    np.testing.assert_allclose(grasps.arrays["support_normal"], [[0.0, 0.0, 1.0]] * 6)
    np.testing.assert_allclose(grasps.arrays["support_offset_m"], 0.3 * grasps.scale, rtol=1e-6)
    init = grasps.arrays["init_pose"]
    assert (init[:, 2] + grasps.arrays["support_offset_m"] >= 0).all()
    assert np.isfinite(grasps.arrays["E_table"]).all()
    import torch

    from dexlite_pipeline.hand.model import ShadowHand

    hand = ShadowHand()
    frames = hand.forward(torch.as_tensor(grasps.hand_pose))
    depth = HandTableClearance(hand).lowest_heights(frames, torch.as_tensor(grasps.arrays["support_normal"]), torch.as_tensor(grasps.arrays["support_offset_m"]))
    np.testing.assert_allclose(grasps.arrays["E_table"], (-depth).clamp(min=0).sum(1).numpy(), atol=1e-6)


def test_floating_mode_reads_no_resting_pose_and_adds_nothing(optim_objects, tmp_path):
    """scene.table false: a stability table without resting poses serves, and the store holds
    exactly the arrays of a floating run (no E_table, no support plane)."""
    plain = tmp_path / "plain.parquet"
    pd.DataFrame({"object_id": ["sphere", "box"], "stable": [False, True]}).to_parquet(plain)
    floating = {**CONFIG, "scene": {"table": False}}
    assert _run(optim_objects, plain, tmp_path / "f.zarr", floating) == 0
    grasps = read_grasp_store(tmp_path / "f.zarr")
    assert grasps.attrs["scene"] == {"table": False}
    assert not {"E_table", "support_normal", "support_offset_m"} & set(grasps.arrays)
    assert _run(optim_objects, plain, tmp_path / "t.zarr") == 2  # tabletop mode needs the resting poses


def test_real_size_optimizes_objects_known_in_metres_at_their_own_scale(optim_objects, tmp_path):
    """With ``real_size`` an object whose file is known to be in metres (it records ``real_radius_m``) gets its real
    scale, 1 / normalization factor, as many starts as the configured scales give; any other object keeps the scales."""
    objects = tmp_path / "objects"
    shutil.copytree(optim_objects, objects)
    meta_path = objects / "assets" / "box" / "meta.json"
    meta = json.loads(meta_path.read_text())
    meta.update(normalization_factor=8.0, real_radius_m=0.11)  # the file's box was 8 times smaller than the normalized one
    meta_path.write_text(json.dumps(meta))
    both_stable = tmp_path / "both_stable.parquet"
    pd.DataFrame({"object_id": ["sphere", "box"], "stable": [True, True], **BOTH_REST}).to_parquet(both_stable)
    real = {**CONFIG, "optimize_grasps": {**CONFIG["optimize_grasps"], "real_size": True}}
    assert _run(objects, both_stable, tmp_path / "real.zarr", real) == 0
    grasps = read_grasp_store(tmp_path / "real.zarr")
    box, sphere = grasps.object_id == "box", grasps.object_id == "sphere"
    assert box.sum() == sphere.sum() == 6  # 3 starts x 2 configured scales each
    np.testing.assert_allclose(grasps.scale[box], 0.125)
    assert sorted(set(grasps.scale[sphere].tolist())) == pytest.approx([0.08, 0.1])
    assert grasps.attrs["objects_at_real_size"] == ["box"]
    np.testing.assert_allclose(grasps.arrays["support_offset_m"][box], 0.3 * 0.125, rtol=1e-6)
