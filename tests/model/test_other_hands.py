"""The learning stages with a hand from its MJCF (the tests' three-finger hand, 9 joints): train -> sample -> post-optimize
through the CLI on a handful of grasps, poses of 6 + 9 numbers throughout, the model file recording the hand, and a
model of one hand refused for another in one line (the shipped Shadow Hand model for Allegro, the three-finger model for
the Shadow Hand)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "hand"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from described_hands import one_line_cli_error  # noqa: E402
from three_finger import write_three_finger  # noqa: E402

from dexlite_pipeline.cli import main  # noqa: E402
from dexlite_pipeline.io.grasp_store import read_grasp_store, write_grasp_store  # noqa: E402

THREE_FINGER_JOINTS = [f"{finger}_j{k}" for finger in ("f1", "f2", "th") for k in range(3)]
POSE_WIDTH = 6 + len(THREE_FINGER_JOINTS)
CONFIG = {
    "seed": 0,
    "device": "cpu",
    "shards": 1,
    "train": {
        "epochs": 2, "max_steps": 0, "batch_size": 8, "clouds_per_batch": 2, "points_per_cloud": 64, "min_grasps": 4,
        "validation_fraction": 0.25, "energy_point_spacing_m": 0.008,
        "energy_weights": {"fc": 0.0, "dis": 1.0, "pen": 1.0, "spen": 1.0, "joints": 1.0, "table": 0.0},  # the hand's energies in the loss
        "model": {"pointnet_widths": [16, 32], "encoder_hidden": [32], "decoder_hidden": [32], "latent_dim": 8, "normalization": "none"},
    },
    "sample": {"synthesis_grasps_per_object": 2, "expansion_grasps_per_object": 2, "scales": [0.08], "shipped_model": "",
               "ladder_grasps_per_object": 1},
    "post_optimize": {"annealing": {"iterations": 4}, "energy_point_spacing_m": 0.008, "batch_size": 8},
    "scene": {"table": False},
}  # fmt: skip


@pytest.fixture(scope="module")
def three_finger_run(tmp_path_factory, sphere_box_objects):
    """The three-finger hand's file, a catalog (box: train, sphere: held out), a stability table and a lift shard of its
    grasps (closed-form poses, ``demo_grasps.facing_grasps``), and the config naming the hand."""
    from demo_grasps import facing_grasps

    from dexlite_pipeline.hand.choice import hand_record
    from dexlite_pipeline.hand.described import DescribedHand

    root = tmp_path_factory.mktemp("three_finger_model")
    xml = write_three_finger(root)
    catalog_dir = root / "catalog"
    catalog_dir.mkdir()
    pd.DataFrame({"object_id": ["box", "sphere"], "status": ["ok", "ok"], "split": ["train", "heldout"]}).to_parquet(catalog_dir / "catalog.parquet")
    pd.DataFrame({"object_id": ["box", "sphere"], "stable": [True, True]}).to_parquet(root / "stability.parquet")
    grasps = facing_grasps(DescribedHand(xml), ("box", "sphere"), 16, seed=7)
    grasps.arrays["lift_success"] = np.arange(16) % 4 != 0
    write_grasp_store(root / "lift.zarr", grasps, hand_record(str(xml)))
    return root, xml, ["--objects", str(catalog_dir), "--objects", str(sphere_box_objects)], {**CONFIG, "hand": str(xml)}


@pytest.fixture(scope="module")
def three_finger_model(three_finger_run):
    """The model trained for the three-finger hand by ``dexlite train-cvae`` (two epochs)."""
    root, _, objects, config = three_finger_run
    model = root / "model" / "cvae.pt"
    outputs = ["--model", str(model), "--history", str(root / "model" / "history.csv"), "--curves", str(root / "model" / "curves.png")]
    assert main(["train-cvae", "--config-json", json.dumps(config), "--lift", str(root / "lift.zarr"), *objects, *outputs]) == 0
    return model


def test_training_for_another_hand_records_it_and_its_pose_length(three_finger_run, three_finger_model):
    from dexlite_pipeline.model.checkpoint import load_checkpoint

    root, xml, _, _ = three_finger_run
    history = pd.read_csv(root / "model" / "history.csv")
    assert len(history) == 2 and np.isfinite(history[["train_recon", "train_pen", "train_spen", "train_joints"]].to_numpy()).all()
    model, checkpoint = load_checkpoint(three_finger_model)
    assert checkpoint["hand"] == str(xml) and checkpoint["joint_names"] == THREE_FINGER_JOINTS and len(checkpoint["hand_sha256"]) == 64
    assert model.joint_count == 9 and model.pose_feature_dim == 9 + 9
    assert tuple(checkpoint["training_grasps"]["hand_pose"].shape[1:]) == (POSE_WIDTH,)
    assert model.decoder[-1].out_features == 18 and len(model.codes_mu) == checkpoint["train_grasps"]


@pytest.fixture(scope="module")
def three_finger_refined(three_finger_run, three_finger_model):
    """``dexlite sample-grasps`` and ``post-optimize`` with the three-finger model: sample.zarr, post.zarr, random.zarr."""
    root, _, objects, config = three_finger_run
    cfg = json.dumps(config)
    common = [*objects, "--shard", "000"]
    assert main(["sample-grasps", "--config-json", cfg, "--model", str(three_finger_model), "--stability", str(root / "stability.parquet"),
                 "--lift", str(root / "lift.zarr"), *common, "--out", str(root / "sample.zarr")]) == 0  # fmt: skip
    assert main(["post-optimize", "--config-json", cfg, "--sample", str(root / "sample.zarr"), *common,
                 "--out", str(root / "post.zarr"), "--random-out", str(root / "random.zarr")]) == 0  # fmt: skip
    return root / "sample.zarr", root / "post.zarr", root / "random.zarr"


def test_sampling_and_refinement_follow_the_hand(three_finger_run, three_finger_refined):
    root, xml, _, _ = three_finger_run
    sample = read_grasp_store(three_finger_refined[0])
    assert sample.hand_pose.shape[1] == POSE_WIDTH and np.isfinite(sample.hand_pose).all()
    assert sample.attrs["hand"] == str(xml) and sample.attrs["joint_names"] == THREE_FINGER_JOINTS
    methods = set(sample.arrays["method"])
    assert {"cvae_raw", "cvae_recon", "cvae_prior_train"} <= methods and methods & {"cvae_expand_latent", "cvae_expand_point"}
    assert sample.arrays["reference_hand_pose"].shape == (len(sample), POSE_WIDTH)

    post = read_grasp_store(three_finger_refined[1])
    assert post.hand_pose.shape == (len(sample), POSE_WIDTH) and np.array_equal(post.arrays["raw_hand_pose"], sample.hand_pose)
    assert np.isfinite(post.arrays["E_post"]).all() and post.attrs["hand"] == str(xml)
    baseline = read_grasp_store(root / "random.zarr")
    assert baseline.hand_pose.shape == (2, POSE_WIDTH)  # the random-start baseline on the held-out sphere's two syntheses


def test_a_model_of_one_hand_is_refused_for_another_in_one_line(three_finger_run, three_finger_model, capsys):
    from dexlite_pipeline.hand.choice import hand_record
    from dexlite_pipeline.model.checkpoint import CheckpointError, load_checkpoint
    from dexlite_pipeline.model.shipped import SHIPPED_MODEL_PATH

    root, xml, objects, config = three_finger_run
    with pytest.raises(CheckpointError) as refused:
        load_checkpoint(three_finger_model, hand=hand_record("shadow"))
    message = str(refused.value)
    assert len(message.splitlines()) == 1 and str(three_finger_model) in message and f"hand {xml}" in message and "shadow" in message
    with pytest.raises(CheckpointError, match=r"a model of hand shadow, this run's hand is allegro"):
        load_checkpoint(SHIPPED_MODEL_PATH, hand=hand_record("allegro"))
    load_checkpoint(three_finger_model, hand=hand_record(str(xml)))  # its own hand loads

    shadow = json.dumps({key: value for key, value in config.items() if key != "hand"})
    error = one_line_cli_error(capsys, ["sample-grasps", "--config-json", shadow, "--model", str(three_finger_model), "--stability",
                                     str(root / "stability.parquet"), *objects, "--shard", "000", "--out", str(root / "refused.zarr")])
    assert f"{three_finger_model}: a model of hand {xml}, this run's hand is shadow" in error
    # the Shadow Hand's training refuses the three-finger hand's lift shard, naming it
    error = one_line_cli_error(capsys, ["train-cvae", "--config-json", shadow, "--lift", str(root / "lift.zarr"), *objects, "--model",
                                     str(root / "no.pt"), "--history", str(root / "no.csv"), "--curves", str(root / "no.png")])
    assert f"{root / 'lift.zarr'} holds grasps of hand {xml}, config key hand is shadow" in error
    assert not (root / "refused.zarr").exists() and not (root / "no.pt").exists()


def test_the_evaluator_reads_the_hands_own_points(three_finger_run):
    """A grasp evaluator for the three-finger hand: ``hand_points_per_shape`` farthest points on each of its 10 geoms, moved
    by its kinematics; saved, it records the hand and is refused for the Shadow Hand in one line."""
    from dexlite_pipeline.hand.choice import hand_record
    from dexlite_pipeline.hand.described import DescribedHand
    from dexlite_pipeline.model.evaluator import EvaluatorConfig, GraspEvaluator, load_evaluator, save_evaluator

    root, xml, _, _ = three_finger_run
    config = EvaluatorConfig(points_per_cloud=64, pointnet_points=32, pointnet_widths=(8, 16), hand_points_per_shape=3, hidden_sizes=(16,))
    evaluator = GraspEvaluator(config, "cpu", str(xml))
    assert evaluator.hand_point_count == 3 * 10 and evaluator.pose_width == POSE_WIDTH
    pose = torch.zeros(2, POSE_WIDTH)
    pose[1, :3] = torch.tensor([0.1, 0.0, 0.0])
    points = evaluator.hand_points(pose)
    assert points.shape == (2, 30, 3) and torch.allclose(points[1] - points[0], torch.tensor([0.1, 0.0, 0.0]).expand(30, 3), atol=1e-6)
    surface = DescribedHand(xml).surface_points_local  # the hand's own surface samples hold every evaluator point (root frame = link frames here)
    assert torch.cdist(points[0][:3], surface).min() < 1e-6
    logits = evaluator(torch.randn(1, 64, 6), pose, torch.zeros(2, dtype=torch.long))
    assert logits.shape == (2, 2)
    save_evaluator(root / "evaluator.pt", evaluator, config)
    loaded, _ = load_evaluator(root / "evaluator.pt", hand=hand_record(str(xml)))
    assert loaded.hand_record["joint_names"] == THREE_FINGER_JOINTS
    with pytest.raises(ValueError, match=r"a grasp evaluator of hand .*three_finger.xml, this run's hand is shadow"):
        load_evaluator(root / "evaluator.pt", hand=hand_record("shadow"))


def test_grasp_rays_of_a_described_hand_run_from_the_palm_toward_the_fingertips(three_finger_run):
    """The three-finger hand at its zero pose (open and flat): the fingers reach +x and the thumb -y in the palm's frame
    and none opposes, so the ray runs from the palm's candidates' centroid toward the mean of the three tips: along +x,
    drawn toward -y by the thumb, nearly in the palm's plane."""
    from dexlite_pipeline.hand.described import DescribedHand
    from dexlite_pipeline.model.association import grasp_rays

    _, xml, _, _ = three_finger_run
    hand = DescribedHand(xml)
    origin, direction = grasp_rays(hand, torch.zeros(1, POSE_WIDTH))
    assert torch.allclose(origin[0], torch.as_tensor(hand.palm_frame_local[:3, 3], dtype=torch.float32), atol=1e-6)
    assert abs(float(direction.norm()) - 1.0) < 1e-6
    assert float(direction[0, 0]) > 0.8 and -0.6 < float(direction[0, 1]) < -0.2 and abs(float(direction[0, 2])) < 0.1


def test_the_evaluator_stages_and_ranking_follow_the_hand(three_finger_run, three_finger_model):
    """evaluator-examples (the model's syntheses refined and simulated in the hand's own scene), train-evaluator on them
    and the lift shard, and sample-grasps ranking a pool with that evaluator: every pose 6 + 9 numbers, the files recording
    the hand."""
    from dexlite_pipeline.model.evaluator import load_evaluator

    root, xml, objects, config = three_finger_run
    config = {**config, "evaluator": {"examples_per_object": 3, "epochs": 2, "hand_points_per_shape": 2, "pool_factor": 2}}
    cfg = json.dumps(config)
    examples = root / "examples.zarr"
    assert main(["evaluator-examples", "--config-json", cfg, "--model", str(three_finger_model), "--stability", str(root / "stability.parquet"),
                 *objects, "--shard", "000", "--out", str(examples)]) == 0  # fmt: skip
    simulated = read_grasp_store(examples)
    assert len(simulated) == 3 and simulated.hand_pose.shape[1] == POSE_WIDTH and set(simulated.object_id) == {"box"}
    assert simulated.arrays["raw_hand_pose"].shape == (3, POSE_WIDTH) and {"lift_success", "six_dir_success"} <= set(simulated.arrays)
    assert simulated.attrs["hand"] == str(xml)

    evaluator = root / "evaluator.pt"
    assert main(["train-evaluator", "--config-json", cfg, "--lift", str(root / "lift.zarr"), "--examples", str(examples), *objects,
                 "--out", str(evaluator), "--facts", str(root / "evaluator.json")]) == 0  # fmt: skip
    model, _ = load_evaluator(evaluator)
    assert model.hand_record["hand"] == str(xml) and model.hand_point_count == 2 * 10

    assert main(["sample-grasps", "--config-json", cfg, "--model", str(three_finger_model), "--stability", str(root / "stability.parquet"),
                 *objects, "--evaluator", str(evaluator), "--shard", "000", "--out", str(root / "ranked.zarr")]) == 0  # fmt: skip
    ranked = read_grasp_store(root / "ranked.zarr")
    rows = ranked.arrays["method"] == "cvae_ranked"
    assert rows.sum() == 2 and ranked.hand_pose.shape[1] == POSE_WIDTH and np.isfinite(ranked.arrays["evaluator_score"][rows]).all()


def test_the_evaluation_follows_the_hand(three_finger_run, three_finger_refined):
    """``dexlite evaluate``: the three-finger hand's sampled, refined and random-start grasps simulated in its scene, their
    energies and the filter's contacts with its model, then tabulated (coverage from its candidates, joint entropy over
    its 9 joints' limits)."""
    root, xml, objects, config = three_finger_run
    sample, post, random_post = three_finger_refined
    cfg = json.dumps({**config, "evaluate": {"methods": ["cvae_raw", "cvae_post", "random_post"], "splits": ["train", "heldout"],
                                             "six_directions": False}})
    simulated = root / "evaluated.zarr"
    assert main(["evaluate", "--step", "simulate", "--config-json", cfg, *objects, "--sample", str(sample), "--post", str(post),
                 "--random-post", str(random_post), "--shard", "0", "--out", str(simulated)]) == 0  # fmt: skip
    grasps = read_grasp_store(simulated)
    assert len(grasps) > 0 and grasps.hand_pose.shape[1] == POSE_WIDTH and grasps.attrs["hand"] == str(xml)
    assert {"lift_success", "E_pen", "filter_E_fc"} <= set(grasps.arrays) and set(grasps.arrays["method"]) == {"cvae_raw", "cvae_post", "random_post"}
    outputs = {name: root / f"eval_{name}" for name in ("metrics", "per-object", "convergence", "budget", "record")}
    assert main(["evaluate", "--step", "aggregate", "--config-json", cfg, *objects, "--sim", str(simulated), "--post", str(post),
                 "--random-post", str(random_post), *[f"--{name}={path}" for name, path in outputs.items()]]) == 0  # fmt: skip
    metrics = pd.read_csv(outputs["metrics"])
    assert set(metrics["method"]) == {"cvae_raw", "cvae_post", "random_post"} and np.isfinite(metrics["joint_entropy_bits"]).any()


@pytest.mark.parametrize("name", ["allegro", "leap"])
def test_grasp_rays_of_the_shipped_hands_leave_the_palm_between_thumb_and_fingers(name):
    """Allegro and LEAP half curled: the ray leaves the palm on its approach side (palm frame z) toward the midpoint of the
    thumb's tip (the opposing finger) and the other three fingers' tips."""
    from dexlite_pipeline.hand.described import DescribedHand
    from dexlite_pipeline.model.association import described_tip_points, grasp_rays

    hand = DescribedHand(name)
    open_hand = torch.as_tensor(hand.description.pregrasp, dtype=torch.float32)
    pose = torch.zeros(1, hand.pose_dim)
    pose[0, 6:] = open_hand + 0.5 * (hand.joint_limits[:, 1] - open_hand)
    _, direction = grasp_rays(hand, pose)
    in_palm = hand.palm_frame_local[:3, :3].T @ direction[0].double().numpy()
    assert in_palm[2] > 0.5, in_palm
    _, _, opposing = described_tip_points(hand)
    assert opposing.tolist() == [False, False, False, True]


def test_the_shipped_model_check_follows_the_models_hand(three_finger_run, three_finger_model):
    """``shipped_model_check`` of the three-finger model: its reconstructions placed by that hand's kinematics (every
    training grasp of the box, fit errors finite) and one synthesis on the held-out sphere lift-tested in its scene."""
    from dexlite_pipeline.model.shipped_check import shipped_model_check
    from dexlite_pipeline.settings import build_config

    _, _, objects, config = three_finger_run
    got = shipped_model_check(three_finger_model, objects[1::2], ["box"], ["sphere"], build_config(config), 1)
    assert got["fit"]["grasps"] > 0 and np.isfinite(got["fit"]["joint_error_rad_mean"]) and np.isfinite(got["fit"]["rotation_error_deg_median"])
    assert got["heldout_raw"]["grasps"] == 1 and set(got["heldout_raw"]["lift_successes_per_object"]) == {"sphere"}
