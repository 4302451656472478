"""The learned grasp evaluator: metrics, example assembly, learning a known rule on unseen objects, ranking, files.

Labels are synthetic: a grasp "holds" iff its palm centre is within ``HOLD_DISTANCE_M`` of the
object surface, a rule the hand-point features expose, so a working evaluator learns it and a
broken one (ignoring the geometry, mixing objects up) does not.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.evaluation.ranking import roc_auc
from dexlite_pipeline.model.evaluator import (
    EvaluatorConfig,
    evaluator_examples,
    load_evaluator,
    save_evaluator,
    score_grasps,
    train_evaluator,
    turned_inputs,
)

HELD_OUT = ("box_wide", "cylinder")
GRASPS_PER_OBJECT = 120
HOLD_DISTANCE_M = 0.03
SMALL_CONFIG = EvaluatorConfig(
    points_per_cloud=256, pointnet_points=64, pointnet_widths=(16, 32, 64), hand_points_per_shape=4,
    hidden_sizes=(64, 32), epochs=12, batch_size=64, learning_rate=2e-3, validation_fraction=0.25, seed=3,
)


def _meshes():
    import trimesh

    ellipsoid = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    ellipsoid.apply_scale([0.95, 0.6, 0.45])
    return {
        "sphere": trimesh.creation.icosphere(subdivisions=2, radius=0.95),
        "box": trimesh.creation.box(extents=(1.2, 0.9, 0.7)),
        "box_long": trimesh.creation.box(extents=(1.6, 0.5, 0.5)),
        "box_wide": trimesh.creation.box(extents=(1.3, 1.1, 0.4)),
        "ellipsoid": ellipsoid,
        "capsule": trimesh.creation.capsule(height=1.0, radius=0.4),
        "cylinder": trimesh.creation.cylinder(radius=0.6, height=1.2),
        "small_sphere": trimesh.creation.icosphere(subdivisions=2, radius=0.6),
    }


@pytest.fixture(scope="module")
def objects_dir(tmp_path_factory):
    """Eight small objects written as prepared assets (coarse SDF, 400 surface samples)."""
    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    root = tmp_path_factory.mktemp("evaluator_objects")
    settings = AssetBuildSettings(sdf_resolution=12, surface_points=400)
    for object_id, mesh in _meshes().items():
        write_asset(mesh, object_id, root, settings, {"source": "test"}, convex_pieces=[mesh])
    return root


def _grasps_with_rule(objects_dir, seed: int) -> GraspSet:
    """Random hand poses facing each object at gaps of -1..7 cm, labelled by the palm-distance rule."""
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix, matrix_to_euler_xyz
    from dexlite_pipeline.objects.assets import load_asset

    hand = ShadowHand()
    rng = np.random.default_rng(seed)
    parts = []
    for object_id in _meshes():
        surface = load_asset(objects_dir, object_id).surface_points
        count = GRASPS_PER_OBJECT
        scale = rng.uniform(0.05, 0.08, count).astype(np.float32)
        rotation = euler_xyz_to_matrix(torch.as_tensor(rng.uniform(-np.pi, np.pi, (count, 3)), dtype=torch.float32))
        gap = torch.as_tensor(rng.uniform(-0.01, 0.07, count), dtype=torch.float32)
        centre_in_palm = torch.stack([torch.full((count,), 0.01), -(torch.as_tensor(scale) * 0.7 + gap), torch.full((count,), 0.07)], 1)
        translation = -(rotation @ centre_in_palm[:, :, None])[:, :, 0]
        limits = hand.joint_limits
        joints = limits[:, 0] + (limits[:, 1] - limits[:, 0]) * torch.as_tensor(rng.uniform(0.2, 0.5, (count, 22)), dtype=torch.float32)
        pose = torch.cat([translation, matrix_to_euler_xyz(rotation), joints], dim=1)
        _, centres = hand.shape_frames(hand.forward(pose))
        palm_centre = centres[:, int(hand.box_ids[0])].numpy()
        distance = np.linalg.norm(palm_centre[:, None, :] - surface[None] * scale[:, None, None], axis=2).min(axis=1)
        parts.append(GraspSet({
            "hand_pose": pose.numpy(), "object_id": np.full(count, object_id, dtype=object), "scale": scale,
            "lift_success": distance < HOLD_DISTANCE_M, "six_dir_success": distance < HOLD_DISTANCE_M * 0.8,
            "failure_reason": np.full(count, "", dtype=object),
        }))
    return GraspSet.concatenate(parts)


@pytest.fixture(scope="module")
def simulated(objects_dir) -> GraspSet:
    return _grasps_with_rule(objects_dir, seed=11)


@pytest.fixture(scope="module")
def trained(objects_dir, simulated):
    """(model, history, training examples) on every object but ``HELD_OUT``; one torch thread."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        train_ids = set(_meshes()) - set(HELD_OUT)
        examples = evaluator_examples([simulated], [str(objects_dir)], train_ids)
        model, history = train_evaluator(examples, SMALL_CONFIG)
    finally:
        torch.set_num_threads(threads)
    return model, history, examples


def _held_out_clouds(objects_dir):
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.objects.assets import load_asset

    return ObjectClouds([load_asset(objects_dir, oid) for oid in HELD_OUT])


def test_evaluator_learns_the_rule_on_held_out_objects(trained, objects_dir, simulated):
    model, history, _ = trained
    assert not set(history.validation_object_ids) & set(history.train_object_ids)
    assert history.validation_object_ids and not set(history.validation_object_ids) & set(HELD_OUT)
    held_out = simulated.select(np.isin(simulated.object_id.astype(str), HELD_OUT))
    labels = held_out.arrays["lift_success"]
    assert 0.2 < labels.mean() < 0.8, "the synthetic rule should give both outcomes"
    scores = score_grasps(model, held_out.hand_pose, _held_out_clouds(objects_dir), held_out.object_id, held_out.scale)
    assert scores.shape == (len(held_out),) and np.all((scores >= 0) & (scores <= 1))
    assert roc_auc(scores, labels) > 0.8


def test_held_out_objects_never_reach_the_training_examples(trained, simulated):
    _, history, examples = trained
    assert not set(examples.object_id.tolist()) & set(HELD_OUT)
    assert not set(examples.clouds.object_ids) & set(HELD_OUT)
    assert not set(history.train_object_ids + history.validation_object_ids) & set(HELD_OUT)
    held_out_count = int(np.isin(simulated.object_id.astype(str), HELD_OUT).sum())
    assert examples.excluded == {"object not in object_ids": held_out_count}
    assert len(examples) == len(simulated) - held_out_count


def test_never_simulated_grasps_are_excluded(objects_dir, simulated):
    grasps = simulated.select(np.arange(30))
    reasons = grasps.arrays["failure_reason"].copy()
    reasons[:4] = "invalid_grasp: no resting pose"
    reasons[4:7] = "not_tested: budget"
    reasons[7:9] = "slipped"  # simulated and failed: a real example
    grasps.arrays["failure_reason"] = reasons
    grasps.arrays["lift_success"] = grasps.arrays["lift_success"].copy()
    grasps.arrays["lift_success"][:7] = True  # whatever they claim, never-simulated grasps must not be labels
    without_six_dir = GraspSet({k: v for k, v in grasps.arrays.items() if k != "six_dir_success"})
    examples = evaluator_examples([grasps, without_six_dir], [str(objects_dir)], None)
    assert examples.excluded == {"never simulated (invalid_grasp)": 8, "never simulated (not_tested)": 6}
    assert len(examples) == 2 * (30 - 7)
    np.testing.assert_array_equal(examples.hand_pose[: 30 - 7], grasps.hand_pose[7:])
    assert examples.six_dir_known.tolist() == [True] * 23 + [False] * 23


def test_save_load_round_trip_gives_identical_scores(trained, objects_dir, simulated, tmp_path):
    model, history, _ = trained
    path = tmp_path / "evaluator.pt"
    save_evaluator(path, model, SMALL_CONFIG, {"best_epoch": history.best_epoch, "train_object_ids": history.train_object_ids})
    loaded, meta = load_evaluator(path)
    assert loaded.config == SMALL_CONFIG and meta["best_epoch"] == history.best_epoch
    held_out = simulated.select(np.isin(simulated.object_id.astype(str), HELD_OUT))
    clouds = _held_out_clouds(objects_dir)
    for head in ("held", "six_dir"):
        before = score_grasps(model, held_out.hand_pose, clouds, held_out.object_id, held_out.scale, head=head)
        after = score_grasps(loaded, held_out.hand_pose, clouds, held_out.object_id, held_out.scale, head=head)
        np.testing.assert_array_equal(before, after)
    assert list(tmp_path.iterdir()) == [path], "the atomic write leaves no temporary file"


def test_training_is_deterministic_for_a_seed(objects_dir, simulated):
    grasps = simulated.select(np.arange(0, len(simulated), 4))
    examples = evaluator_examples([grasps], [str(objects_dir)], None)
    config = EvaluatorConfig(**{**SMALL_CONFIG.__dict__, "epochs": 2})
    first, first_history = train_evaluator(examples, config)
    second, second_history = train_evaluator(examples, config)
    def without_timing(rows):
        return [{k: v for k, v in row.items() if k != "seconds"} for row in rows]

    assert without_timing(first_history.epochs) == without_timing(second_history.epochs)
    for name, value in first.state_dict().items():
        assert torch.equal(value, second.state_dict()[name]), name


def test_turned_inputs_keep_the_hand_object_geometry(trained, objects_dir, simulated):
    """The augmentation turns cloud, grasps and table together: every height and distance the network reads is unchanged,
    positions and normals turn, and a grasp's table stays under it."""
    from dexlite_pipeline.model.evaluator import _batch_inputs
    from dexlite_pipeline.model.data import ObjectClouds, cloud_keys
    from dexlite_pipeline.objects.assets import load_asset

    model = trained[0]
    grasps = simulated.select(np.arange(0, len(simulated), 37))
    ids = sorted(set(grasps.object_id.tolist()))
    clouds = ObjectClouds([load_asset(objects_dir, oid) for oid in ids])
    object_index = np.array([clouds.index_of[o] for o in grasps.object_id], dtype=np.int64)
    support = np.tile(np.array([[0, 0, 1, 0.05]], np.float32), (len(grasps), 1))
    keys = cloud_keys(grasps.object_id, grasps.scale)
    inputs = _batch_inputs(clouds, object_index, grasps.scale, grasps.hand_pose, support, keys, np.arange(len(grasps)), 256, "cpu")
    angle = torch.linspace(0.3, 5.9, len(inputs[0]))
    turned = turned_inputs(inputs, angle)
    with torch.no_grad():
        plain = model.hand_point_features(inputs[0][inputs[2]], model.hand_points(inputs[1]), inputs[3])
        moved = model.hand_point_features(turned[0][turned[2]], model.hand_points(turned[1]), turned[3])
    assert torch.allclose(plain[..., 3:5], moved[..., 3:5], atol=1e-4)  # height above and distance to the surface
    assert torch.allclose(plain[..., 8], moved[..., 8], atol=1e-4)  # height above the table
    assert torch.allclose(turned[3], inputs[3])  # an upright table's normal is the turn's axis
    assert not torch.allclose(plain[..., :3], moved[..., :3], atol=1e-3)  # positions turned
