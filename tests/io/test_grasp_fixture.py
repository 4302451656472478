"""The committed grasp fixture (tests/fixtures/pybullet_grasps): DexGraspNet's structure, and grasps
that the project's importer, energies and lift test treat as the real grasps they are.

The fixture holds grasps the pipeline's optimization from scratch found on two pybullet_data objects and its
lift test held, kept only if they held again after export and re-import
(tests/fixtures/make_grasp_fixture.py). Imported here with the same settings as there, every one
must hold, and the same grasps moved away from the object must all drop it.
"""

from __future__ import annotations

import numpy as np
import pytest
from asset_checks import assert_sdf_sign_matches_pieces
from fixtures.make_grasp_fixture import MAX_GRASPS_PER_OBJECT, import_settings, pipeline_config
from sample_data import DEXGRASPNET_QPOS_ORDER, FIXTURE_HELDOUT_OBJECT, FIXTURE_TRAIN_OBJECT, GRASP_FIXTURE

from dexlite_pipeline.io.dexgraspnet import DexGraspNetConfig, import_dexgraspnet
from dexlite_pipeline.io.safe_pickle import load_npy_restricted
from dexlite_pipeline.objects.assets import load_asset
from dexlite_pipeline.sim.lift import run_lift_tests

OBJECTS = (FIXTURE_HELDOUT_OBJECT, FIXTURE_TRAIN_OBJECT)  # file order


def test_fixture_files_are_in_dexgraspnets_structure():
    assert sorted(p.name for p in (GRASP_FIXTURE / "dataset").iterdir()) == [f"{o}.npy" for o in OBJECTS]
    for object_id in OBJECTS:
        entries = load_npy_restricted(GRASP_FIXTURE / "dataset" / f"{object_id}.npy")  # no code runs
        assert entries.dtype == object and entries.ndim == 1 and 1 <= len(entries) <= MAX_GRASPS_PER_OBJECT
        for entry in entries:
            assert list(entry) == ["qpos", "scale"] and list(entry["qpos"]) == list(DEXGRASPNET_QPOS_ORDER)
            assert all(type(v) is float for v in entry["qpos"].values()) and type(entry["scale"]) is np.float64
        mesh = (GRASP_FIXTURE / "meshdata" / object_id / "coacd" / "decomposed.obj").read_text()
        assert mesh.startswith("o convex_0\n")
    size = sum(p.stat().st_size for p in GRASP_FIXTURE.rglob("*") if p.is_file())
    assert size < 100_000


@pytest.fixture(scope="module")
def imported_fixture(tmp_path_factory):
    """The fixture imported with the settings it was made with (config.yaml's), with the config."""
    config = pipeline_config()
    objects = tmp_path_factory.mktemp("fixture_objects")
    result = import_dexgraspnet(GRASP_FIXTURE, objects, import_settings(config), DexGraspNetConfig(), seed=config.seed)
    return result, objects, config


def test_fixture_imports_whole_with_correct_sdf_sign(imported_fixture):
    import trimesh

    result, objects, _ = imported_fixture
    in_files = sum(len(load_npy_restricted(path)) for path in (GRASP_FIXTURE / "dataset").glob("*.npy"))
    assert result.problems == [] and len(result.grasps) == in_files
    assert sorted(set(result.grasps.object_id)) == sorted(OBJECTS)
    rng = np.random.default_rng(0)
    for object_id in OBJECTS:
        asset = load_asset(objects, object_id)
        soup = trimesh.load(GRASP_FIXTURE / "meshdata" / object_id / "coacd" / "decomposed.obj", force="mesh", process=False)
        assert_sdf_sign_matches_pieces(asset, soup, rng)


def test_fixture_grasps_meet_the_energy_thresholds_they_were_kept_for(imported_fixture):
    """Optimization from scratch kept them below the penetration and contact-distance thresholds on these very
    meshes: a frame or conversion error would show as deep penetration or far contacts."""
    from dexlite_pipeline.energy.per_grasp import evaluate_grasp_energies
    from dexlite_pipeline.hand import JOINT_NAMES

    result, objects, config = imported_fixture
    thresholds = config.optimize_grasps.thresholds
    energies = evaluate_grasp_energies(result.grasps, [objects], config=config.energy)
    assert (energies["E_pen"] < thresholds.max_e_pen_m).all() and (energies["E_dis"] < thresholds.max_e_dis_m).all()
    assert (energies["penetration_mm"] <= 1000 * thresholds.max_penetration_m).all()
    # control: the same grasps with the four fingers closed through the object
    closed = result.grasps.select(np.arange(len(result.grasps)))
    finger_flexion = [6 + i for i, name in enumerate(JOINT_NAMES) if name[-2:] in ("J2", "J1", "J0") and "TH" not in name]
    closed.arrays["hand_pose"] = closed.hand_pose.copy()
    closed.hand_pose[:, finger_flexion] = 1.571
    closed_energies = evaluate_grasp_energies(closed, [objects], config=config.energy)
    assert np.median(closed_energies["E_pen"]) > 10 * thresholds.max_e_pen_m
    assert np.median(closed_energies["penetration_mm"]) > 5.0


@pytest.mark.slow
def test_every_fixture_grasp_holds_in_the_lift_test(imported_fixture):
    result, objects, config = imported_fixture
    lift = run_lift_tests(result.grasps, [objects], config.lift, threads=1)
    assert lift["lift_success"].all(), f"{int((~lift['lift_success']).sum())} fixture grasps dropped: {set(lift['failure_reason'])}"
    assert (lift["initial_penetration_mm"] <= 1000 * config.lift.max_initial_penetration_m).all()


@pytest.mark.slow
def test_fixture_grasps_moved_away_all_fail(imported_fixture):
    result, objects, config = imported_fixture
    away = result.grasps.select(np.arange(len(result.grasps)))
    away.arrays["hand_pose"] = away.hand_pose.copy()
    away.arrays["hand_pose"][:, :3] *= 1.0 + 0.5 / np.linalg.norm(away.hand_pose[:, :3], axis=1, keepdims=True)  # 0.5 m further out
    lift = run_lift_tests(away, [objects], config.lift, threads=1)
    assert not lift["lift_success"].any()
    assert set(lift["failure_reason"]) == {"dropped"}
