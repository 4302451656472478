"""Curation: drop reasons, near-duplicates, the per-object cap, the summary and the CLI steps."""

import json
import math

import numpy as np
import pandas as pd
import pytest

from dexlite_pipeline.cli import main as dexlite
from dexlite_pipeline.energy.config import EnergyThresholds
from dexlite_pipeline.curation.config import CurateConfig
from dexlite_pipeline.curation.filters import DROP_REASONS, ObjectFacts, curate_grasps, near_duplicates, summarize
from dexlite_pipeline.curation.force_closure import ForceClosureResult
from dexlite_pipeline.io.grasp_store import GraspSet, empty_grasp_set, read_grasp_store, write_grasp_store
from dexlite_pipeline.curation.shard import _common_arrays, tag_origin as _tag

GOOD = {"E_fc": 0.05, "E_dis": 0.001, "E_pen": 0.0002}


def _pose(t=(0.0, 0.0, 0.1), euler=(0.0, 0.0, 0.0), joint=0.3):
    pose = np.full(28, joint)
    pose[:3], pose[3:6] = t, euler
    return pose


def _grasp_set(rows):
    """rows: (object_id, pose, scale, energies dict)."""
    return GraspSet(
        {
            "hand_pose": np.stack([r[1] for r in rows]).astype(np.float32),
            "object_id": np.array([r[0] for r in rows], dtype=object),
            "scale": np.array([r[2] for r in rows], np.float32),
            **{t: np.array([r[3][t] for r in rows], np.float32) for t in ("E_fc", "E_dis", "E_pen")},
            "penetration_mm": np.array([r[3].get("penetration_mm", 0.5) for r in rows], np.float32),
        }
    )


FACTS = ObjectFacts(
    status={"a": "ok", "held": "ok", "wobbly": "ok", "bad": "rejected", "untested": "ok"},
    split={"a": "train", "held": "heldout", "wobbly": "train", "bad": "train", "untested": "train"},
    stable={"a": True, "held": True, "wobbly": False, "bad": True},
)


def test_each_grasp_gets_the_first_reason_that_applies():
    nan_pose = _pose()
    nan_pose[7] = np.nan
    rows = [
        ("a", _pose(), 0.1, GOOD),  # kept
        ("a", _pose(t=(0.05, 0, 0.1)), 0.1, {**GOOD, "E_fc": 0.5}),
        ("a", _pose(t=(0.10, 0, 0.1)), 0.1, {**GOOD, "E_dis": 0.006}),
        ("a", _pose(t=(0.15, 0, 0.1)), 0.1, {**GOOD, "E_pen": 0.002}),
        ("a", _pose(t=(0.20, 0, 0.1)), 0.1, {"E_fc": 0.5, "E_dis": 0.006, "E_pen": 0.002}),
        ("a", _pose(t=(0.25, 0, 0.1)), 0.1, {**GOOD, "E_fc": np.nan}),
        ("a", nan_pose, 0.1, GOOD),
        ("held", _pose(), 0.1, GOOD),
        ("wobbly", _pose(), 0.1, GOOD),
        ("bad", _pose(), 0.1, GOOD),
        ("untested", _pose(), 0.1, GOOD),
        ("nowhere", _pose(), 0.1, GOOD),
        ("held", _pose(), 0.1, {**GOOD, "E_fc": 0.9}),  # object reasons come before energies
        ("a", _pose(t=(0.30, 0, 0.1)), 0.1, {**GOOD, "penetration_mm": 2.01}),  # starts deeper than the 2 mm cap
        ("a", _pose(t=(0.35, 0, 0.1)), 0.1, {**GOOD, "penetration_mm": 2.0}),  # exactly at the cap: allowed
    ]
    reasons = curate_grasps(_grasp_set(rows), FACTS, CurateConfig(force_closure=False))
    assert list(reasons) == [
        "", "e_fc", "e_dis", "e_pen", "e_fc", "invalid_grasp", "invalid_grasp",
        "not_train", "unstable", "object_not_ok", "no_stability_result", "object_not_ok", "not_train",
        "penetration_mm", "",
    ]


def test_thresholds_are_strict_and_configurable():
    rows = [("a", _pose(t=(0.05 * i, 0, 0.1)), 0.1, {**GOOD, "E_fc": fc}) for i, fc in enumerate([0.29, 0.3, 0.31])]
    assert list(curate_grasps(_grasp_set(rows), FACTS, CurateConfig(force_closure=False))) == ["", "e_fc", "e_fc"]
    assert list(curate_grasps(_grasp_set(rows), FACTS, CurateConfig(force_closure=False, thresholds=EnergyThresholds(max_e_fc=0.305)))) == ["", "", "e_fc"]


def test_near_duplicate_needs_all_three_tolerances():
    config = CurateConfig(force_closure=False, duplicate_translation_m=0.005, duplicate_rotation_deg=10.0, duplicate_joint_rad=0.1)
    best = _pose()
    close_joint = _pose(joint=0.39)
    poses = [
        best,
        _pose(t=(0.003, 0.002, 0.1), euler=(math.radians(6), 0, 0), joint=0.35),  # duplicate of best
        _pose(t=(0.006, 0.0, 0.1)),  # 6 mm away
        _pose(euler=(0, 0, math.radians(11))),  # 11 degrees about z
        _pose(euler=(math.radians(8), math.radians(8), 0)),  # ~11.3 degrees in all
        _pose(joint=0.41),  # every joint 0.11 rad away
        close_joint,  # 0.09 rad: duplicate of best
    ]
    single_joint = _pose()
    single_joint[6 + 21] += 0.2  # one joint differs: THJ0
    poses.append(single_joint)
    order = np.arange(len(poses))
    assert list(near_duplicates(np.stack(poses), order, config)) == [False, True, False, False, False, False, True, False]
    # ranking decides which of two duplicates survives
    assert list(near_duplicates(np.stack([best, close_joint]), np.array([1, 0]), config)) == [True, False]


def test_deduplication_keeps_the_better_grasp_and_only_within_one_scale():
    worse = {"E_fc": 0.2, "E_dis": 0.003, "E_pen": 0.0005}
    rows = [
        ("a", _pose(t=(0.001, 0, 0.1)), 0.1, worse),
        ("a", _pose(), 0.1, GOOD),
        ("a", _pose(), 0.12, worse),  # same pose, other object size: not a duplicate
    ]
    assert list(curate_grasps(_grasp_set(rows), FACTS, CurateConfig(force_closure=False))) == ["duplicate", "", ""]


def test_cap_keeps_the_best_grasps_of_each_object():
    rows = [("a", _pose(t=(0.02 * i, 0, 0.1)), 0.06 + 0.02 * (i % 2), {**GOOD, "E_fc": 0.25 - 0.05 * i}) for i in range(5)]
    rows.append(("untested", _pose(), 0.1, GOOD))
    reasons = curate_grasps(_grasp_set(rows), FACTS, CurateConfig(force_closure=False, max_grasps_per_object=2))
    assert list(reasons) == ["cap", "cap", "cap", "", "", "no_stability_result"]
    assert list(curate_grasps(_grasp_set(rows), FACTS, CurateConfig(force_closure=False, max_grasps_per_object=0)))[:5] == [""] * 5


def test_summary_counts_add_up_per_object_and_origin():
    rows = [("a", _pose(t=(0.05 * i, 0, 0.1)), 0.1, {**GOOD, "E_pen": 0.0004 * i}) for i in range(4)] + [("held", _pose(), 0.1, GOOD)]
    grasps = _grasp_set(rows)
    grasps.arrays["origin"] = np.array(["optimization", "optimization", "dexgraspnet", "dexgraspnet", "optimization"], dtype=object)
    config = CurateConfig(force_closure=False, imported_thresholded_terms=("E_fc", "E_dis", "E_pen"))
    table = summarize(grasps, curate_grasps(grasps, FACTS, config), FACTS).set_index(["object_id", "origin"])
    assert table.loc[("a", "optimization"), "n_kept"] == 2 and table.loc[("a", "dexgraspnet"), "n_kept"] == 1
    assert table.loc[("a", "dexgraspnet"), "dropped_e_pen"] == 1
    assert table.loc[("held", "optimization"), "dropped_not_train"] == 1 and table.loc[("held", "optimization"), "split"] == "heldout"
    dropped = table[[f"dropped_{r}" for r in DROP_REASONS]].sum(axis=1)
    assert ((table["n_kept"] + dropped) == table["n_input"]).all()


def test_imported_grasps_are_held_to_the_configured_terms_only():
    failing = [{**GOOD, "E_fc": 0.5}, {**GOOD, "E_dis": 0.006}, {**GOOD, "E_pen": 0.002}]
    rows = [("a", _pose(t=(0.05 * i, 0, 0.1)), 0.1, e) for i, e in enumerate(failing * 2)]
    grasps = _grasp_set(rows)
    grasps.arrays["origin"] = np.array(["optimization"] * 3 + ["dexgraspnet"] * 3, dtype=object)
    assert list(curate_grasps(grasps, FACTS, CurateConfig(force_closure=False))) == ["e_fc", "e_dis", "e_pen", "", "e_dis", ""]
    only_pen = CurateConfig(force_closure=False, imported_thresholded_terms=("E_pen",))
    assert list(curate_grasps(grasps, FACTS, only_pen)) == ["e_fc", "e_dis", "e_pen", "", "", "e_pen"]


def test_optimized_grasps_are_held_to_the_configured_terms_only():
    failing = [{**GOOD, "E_fc": 0.5}, {**GOOD, "E_dis": 0.006}, {**GOOD, "E_pen": 0.002}, {**GOOD, "penetration_mm": 2.5}]
    rows = [("a", _pose(t=(0.05 * i, 0, 0.1)), 0.1, e) for i, e in enumerate(failing * 2)]
    grasps = _grasp_set(rows)
    grasps.arrays["origin"] = np.array(["optimization"] * 4 + ["dexgraspnet"] * 4, dtype=object)
    without_fc = CurateConfig(force_closure=False, optimized_thresholded_terms=("E_dis", "E_pen", "penetration_mm"))
    assert list(curate_grasps(grasps, FACTS, without_fc)) == ["", "e_dis", "e_pen", "penetration_mm", "", "e_dis", "", ""]
    assert list(curate_grasps(grasps, FACTS, CurateConfig(force_closure=False)))[:4] == ["e_fc", "e_dis", "e_pen", "penetration_mm"]


def test_force_closure_drops_grasps_whose_contacts_do_not_close():
    rows = [("a", _pose(t=(0.05 * i, 0, 0.1)), 0.1, GOOD) for i in range(4)]
    rows.insert(1, ("a", _pose(t=(0.5, 0, 0.1)), 0.1, {**GOOD, "E_dis": 0.006}))
    rows.append(("held", _pose(), 0.1, GOOD))
    grasps = _grasp_set(rows)
    epsilon_by_x = {0.0: 0.05, 0.05: 0.0, 0.1: 0.01, 0.15: 0.2}
    seen = []

    def evaluator(subset):
        seen.append(len(subset))
        return ForceClosureResult(np.array([epsilon_by_x[round(float(x), 2)] for x in subset.hand_pose[:, 0]]), np.full(len(subset), "", dtype=object))

    reasons = curate_grasps(grasps, FACTS, CurateConfig(force_closure=True, force_closure_min_epsilon=0.01), evaluator)
    assert list(reasons) == ["", "e_dis", "force_closure", "force_closure", "", "not_train"]  # epsilon must exceed the minimum
    assert seen == [4]  # called once, on the grasps that passed every earlier check
    np.testing.assert_allclose(grasps.arrays["force_closure_epsilon"], [0.05, np.nan, 0.0, 0.01, 0.2, np.nan])
    any_closure = CurateConfig(force_closure=True, force_closure_min_epsilon=0.0)
    assert list(curate_grasps(_grasp_set(rows), FACTS, any_closure, evaluator))[2:4] == ["force_closure", ""]
    assert list(curate_grasps(_grasp_set(rows), FACTS, CurateConfig(force_closure=False), evaluator))[2:4] == ["", ""]
    with pytest.raises(ValueError, match="force-closure evaluator"):
        curate_grasps(_grasp_set(rows), FACTS, CurateConfig(force_closure=True))


def test_grasps_whose_force_closure_could_not_be_computed_are_dropped_with_the_reason():
    rows = [("a", _pose(t=(0.05 * i, 0, 0.1)), 0.1, GOOD) for i in range(3)]
    grasps = _grasp_set(rows)

    def evaluator(subset):
        return ForceClosureResult(np.array([0.05, np.nan, 0.2]), np.array(["", "object asset unusable: damaged", ""], dtype=object))

    reasons = curate_grasps(grasps, FACTS, CurateConfig(force_closure=True), evaluator)
    assert list(reasons) == ["", "force_closure_unknown", ""]
    assert list(grasps.arrays["force_closure_failure_reason"]) == ["", "object asset unusable: damaged", ""]


def test_empty_input_sets_do_not_decide_the_shared_arrays():
    """An optimized shard without grasps (and without energy arrays) must not strip the imported grasps' energies."""
    empty_optimized = _tag(empty_grasp_set(), "optimization")
    imported = _grasp_set([("a", _pose(t=(0.05 * i, 0, 0.1)), 0.1, {**GOOD, "E_pen": 0.002}) for i in range(2)])
    imported.arrays["source_index"] = np.arange(2)
    merged = _common_arrays([empty_optimized, _tag(imported, "dexgraspnet")])
    assert set(merged.arrays) == {"hand_pose", "object_id", "scale", "E_fc", "E_dis", "E_pen", "penetration_mm", "source_index", "origin", "origin_index"}
    np.testing.assert_array_equal(merged.arrays["E_pen"], imported.arrays["E_pen"])
    assert list(curate_grasps(merged, FACTS, CurateConfig(force_closure=False))) == ["", ""]  # imported: held to E_dis only
    assert len(_common_arrays([empty_optimized])) == 0 and list(curate_grasps(_common_arrays([empty_optimized]), FACTS, CurateConfig(force_closure=False))) == []


def test_config_rejects_nonsense():
    with pytest.raises(ValueError, match="max_e_fc"):
        CurateConfig(thresholds=EnergyThresholds(max_e_fc=0))
    with pytest.raises(ValueError, match="E_foo"):
        CurateConfig(imported_thresholded_terms=("E_foo",))
    with pytest.raises(ValueError, match="optimized_thresholded_terms: unknown term.s. E_bar"):
        CurateConfig(optimized_thresholded_terms=("E_bar",))
    with pytest.raises(ValueError, match="force_closure_min_epsilon"):
        CurateConfig(force_closure_min_epsilon=-0.1)


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    """Two prepared box objects (catalog, stability), an optimized shard, and imported grasps."""
    import trimesh

    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    root = tmp_path_factory.mktemp("curate")
    settings = AssetBuildSettings(sdf_resolution=24, sdf_padding=0.3, surface_points=256)
    box = trimesh.creation.box(extents=(1.2, 0.8, 0.6))
    for object_id in ("box0", "box1"):
        write_asset(box, object_id, root / "objects", settings, {"source": "test"}, convex_pieces=[box])
    catalog = pd.DataFrame(
        {"object_id": ["box0", "box1"], "source": "test", "file": "", "watertight": True, "volume": 0.576,
         "n_convex_pieces": 1, "status": "ok", "reason": "", "split": ["train", "heldout"]}
    )
    catalog.to_parquet(root / "objects" / "catalog.parquet")
    # Resting poses: each box lies flat, its table 0.3 below its origin per unit scale (z = -0.03 m at scale 0.1).
    rest = {"support_nx": 0.0, "support_ny": 0.0, "support_nz": 1.0, "support_offset": 0.3}
    pd.DataFrame({"object_id": ["box0", "box1"], "lateral_displacement_m": 0.0, "rotation_deg": 0.0, "stable": True, "reason": "", **rest}).to_parquet(
        root / "stability.parquet"
    )
    optimized = _grasp_set([("box0", _pose(), 0.1, GOOD), ("box0", _pose(t=(0.05, 0, 0.1)), 0.1, {**GOOD, "E_dis": 0.01})])
    write_grasp_store(root / "optimized_000.zarr", optimized)
    far = _pose(t=(0.0, 0.0, 0.5))  # 40 cm above the box: no contact
    imported = GraspSet(
        {
            "hand_pose": np.stack([far, far, far]).astype(np.float32),
            "object_id": np.array(["box0", "box1", "box0"], dtype=object),
            "scale": np.full(3, 0.1, np.float32),
            "source_file": np.array(["dataset/box0.npy", "dataset/box1.npy", "dataset/box0.npy"], dtype=object),
            "source_index": np.arange(3),
        }
    )
    write_grasp_store(root / "imported.zarr", imported)
    return root


def test_cli_curates_a_shard_with_imported_grasps_and_aggregates(workspace):
    root = workspace
    config = json.dumps({"shards": 2, "device": "cpu", "curate": {"thresholds": {"max_e_fc": 100.0}, "force_closure": False}})  # E_fc never binds: far hands fail on E_dis
    summaries = []
    for shard in (0, 1):
        args = ["curate", "--step", "curate", "--shard", str(shard), "--config-json", config, "--stability", str(root / "stability.parquet"),
                "--objects", str(root / "objects"), "--imported", str(root / "imported.zarr"),
                "--out", str(root / f"curate_{shard}.zarr"), "--summary-out", str(root / f"summary_{shard}.csv")]
        if shard == 0:
            args += ["--optimized-grasps", str(root / "optimized_000.zarr")]
        assert dexlite(args) == 0
        summaries.append(str(root / f"summary_{shard}.csv"))
    kept = read_grasp_store(root / "curate_0.zarr")
    assert len(kept) == 1 and kept.arrays["origin"][0] == "optimization" and kept.arrays["origin_index"][0] == 0
    assert kept.attrs["dropped"]["e_dis"] == 3 and kept.attrs["n_input"] == 4
    assert "source_file" not in kept.arrays  # only arrays every input has
    assert len(read_grasp_store(root / "curate_1.zarr")) == 0

    assert dexlite(["curate", "--step", "aggregate", "--summary", summaries[0], "--summary", summaries[1], "--out", str(root / "summary.csv")]) == 0
    table = pd.read_csv(root / "summary.csv", keep_default_na=False).set_index(["object_id", "origin"])
    assert table.loc[("box0", "optimization"), "n_kept"] == 1 and table.loc[("box0", "optimization"), "dropped_e_dis"] == 1
    assert table.loc[("box0", "dexgraspnet"), "dropped_e_dis"] == 2
    assert table.loc[("box1", "dexgraspnet"), "dropped_not_train"] == 1
    assert table["n_input"].sum() == 5


def test_aggregate_refuses_overlapping_shards(tmp_path):
    row = pd.DataFrame([{"object_id": "a", "origin": "optimization", "n_input": 1, "n_kept": 1}])
    row.to_csv(tmp_path / "s0.csv", index=False)
    row.to_csv(tmp_path / "s1.csv", index=False)
    code = dexlite(["curate", "--step", "aggregate", "--summary", str(tmp_path / "s0.csv"), "--summary", str(tmp_path / "s1.csv"), "--out", str(tmp_path / "m.csv")])
    assert code == 2 and not (tmp_path / "m.csv").exists()


def test_cli_force_closure_drops_a_grasp_that_touches_nothing(workspace):
    root = workspace
    config = json.dumps({"shards": 2, "device": "cpu", "curate": {"force_closure": True}})
    args = ["curate", "--step", "curate", "--shard", "0", "--config-json", config, "--stability", str(root / "stability.parquet"),
            "--objects", str(root / "objects"), "--optimized-grasps", str(root / "optimized_000.zarr"),
            "--out", str(root / "fc_0.zarr"), "--summary-out", str(root / "fc_summary_0.csv")]
    assert dexlite(args) == 0
    kept = read_grasp_store(root / "fc_0.zarr")
    assert len(kept) == 0 and kept.attrs["dropped"]["force_closure"] == 1 and kept.attrs["dropped"]["e_dis"] == 1
    assert kept.attrs["config"]["curate"]["force_closure_friction"] == 0.6
    assert pd.read_csv(root / "fc_summary_0.csv").loc[0, "dropped_force_closure"] == 1


def _curate_args(root, shard_name, config, objects=None, optimized=None, imported=None, stability=None):
    args = ["curate", "--step", "curate", "--shard", "0", "--config-json", json.dumps(config),
            "--stability", str(stability or root / "stability.parquet"), "--objects", str(objects or root / "objects"),
            "--out", str(root / f"{shard_name}.zarr"), "--summary-out", str(root / f"{shard_name}.csv")]
    if optimized:
        args += ["--optimized-grasps", str(optimized)]
    if imported:
        args += ["--imported", str(imported)]
    return args


def test_cli_empty_optimized_shard_keeps_the_imported_grasps_and_their_energies(workspace):
    """An empty optimized shard (as the optimize stage writes one without usable objects) no longer strips E_* from imported grasps."""
    root = workspace
    write_grasp_store(root / "optimized_empty.zarr", empty_grasp_set())
    config = {"shards": 1, "device": "cpu", "curate": {"thresholds": {"max_e_dis_m": 100.0}, "force_closure": False}}  # imported grasps are held to E_dis only
    assert dexlite(_curate_args(root, "from_empty_optimized", config, optimized=root / "optimized_empty.zarr", imported=root / "imported.zarr")) == 0
    kept = read_grasp_store(root / "from_empty_optimized.zarr")
    assert len(kept) == 1 and kept.arrays["origin"][0] == "dexgraspnet"
    assert kept.attrs["dropped"]["duplicate"] == 1 and kept.attrs["dropped"]["not_train"] == 1  # box0's two imported grasps are one pose
    for term in ("E_fc", "E_dis", "E_pen"):
        assert np.isfinite(kept.arrays[term]).all()


def test_cli_stability_table_without_stable_is_a_one_line_error(workspace, tmp_path, capsys):
    malformed = tmp_path / "malformed.parquet"
    pd.DataFrame({"object_id": ["box0"], "is_stable": [True]}).to_parquet(malformed)
    args = _curate_args(tmp_path, "out", {"shards": 1}, objects=workspace / "objects", optimized=workspace / "optimized_000.zarr", stability=malformed)
    assert dexlite(args) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "malformed.parquet" in error and "stable" in error
    assert not (tmp_path / "out.zarr").exists()


def test_cli_force_closure_of_a_damaged_asset_drops_its_grasps_with_the_reason(workspace, tmp_path, capsys):
    import shutil

    objects = tmp_path / "objects"
    shutil.copytree(workspace / "objects", objects)
    (objects / "assets" / "box0" / "meta.json").write_text("{not json")
    config = {"shards": 1, "device": "cpu", "curate": {"force_closure": True}}
    args = _curate_args(tmp_path, "fc", config, objects=objects, optimized=workspace / "optimized_000.zarr", stability=workspace / "stability.parquet")
    assert dexlite(args) == 0
    kept = read_grasp_store(tmp_path / "fc.zarr")
    assert len(kept) == 0 and kept.attrs["dropped"]["force_closure_unknown"] == 1 and kept.attrs["dropped"]["e_dis"] == 1
    (reason, count), = kept.attrs["force_closure_failures"].items()
    assert count == 1 and "object 'box0'" in reason and "meta.json" in reason
    assert reason in capsys.readouterr().out
    assert pd.read_csv(tmp_path / "fc.csv").loc[0, "dropped_force_closure_unknown"] == 1


def test_cli_tabletop_drops_imported_grasps_below_the_table_with_the_reason(workspace, tmp_path):
    """Tabletop mode (the default): an imported hand under the box (in its table) is dropped as below_table,
    counted in the summary; floating mode curates the same input exactly as before (no such reason or column)."""
    below = _pose(t=(0.0, 0.0, -0.2))  # 17 cm under the box's base
    above = _pose(t=(0.0, 0.0, 0.5))
    imported = GraspSet(
        {
            "hand_pose": np.stack([below, above]).astype(np.float32),
            "object_id": np.array(["box0", "box0"], dtype=object),
            "scale": np.full(2, 0.1, np.float32),
        }
    )
    write_grasp_store(tmp_path / "imported.zarr", imported)
    write_grasp_store(tmp_path / "optimized_empty.zarr", empty_grasp_set())
    config = {"shards": 1, "device": "cpu", "curate": {"force_closure": False}}
    root = workspace
    for name, scene in (("tabletop", {}), ("floating", {"scene": {"table": False}})):
        args = _curate_args(tmp_path, name, {**config, **scene}, objects=root / "objects", optimized=tmp_path / "optimized_empty.zarr",
                            imported=tmp_path / "imported.zarr", stability=root / "stability.parquet")
        assert dexlite(args) == 0
    tabletop = read_grasp_store(tmp_path / "tabletop.zarr")
    assert tabletop.attrs["dropped"]["below_table"] == 1 and tabletop.attrs["scene"] == {"table": True}
    assert pd.read_csv(tmp_path / "tabletop.csv").loc[0, "dropped_below_table"] == 1
    floating = read_grasp_store(tmp_path / "floating.zarr")
    assert "below_table" not in floating.attrs["dropped"] and "scene" not in floating.attrs
    assert list(pd.read_csv(tmp_path / "floating.csv").columns) == ["object_id", "origin", "split", "stable", "n_input", "n_kept", *(f"dropped_{r}" for r in DROP_REASONS)]
    assert floating.attrs["dropped"]["e_dis"] == 2  # both far hands fail the contact distance, as before
