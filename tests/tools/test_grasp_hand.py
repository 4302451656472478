"""``dexlite grasp --hand``: a hand from its MJCF (the tests' three-finger hand) end to end with ``--from-scratch`` and
with a model (and an evaluator) made for it; with the Shadow Hand's model, without a model for a hand none ships for, a
model or evaluator of another hand and a broken MJCF, one line and exit status 2."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "hand"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from described_hands import one_line_cli_error, untrained_model_and_evaluator  # noqa: E402
from three_finger import write_three_finger  # noqa: E402

from dexlite_pipeline.cli import main  # noqa: E402
from dexlite_pipeline.io.grasp_store import read_grasp_store  # noqa: E402

TINY = {
    "objects": {"sdf_resolution": 32, "surface_points": 512, "coacd_mcts_iterations": 10, "coacd_mcts_nodes": 5,
                "coacd_mcts_max_depth": 1, "coacd_resolution": 300},
    "energy": {"object_point_spacing_m": 0.004},
    "optimize_grasps": {"annealing": {"iterations": 30}, "final_contact_samples": 16, "contact_search_every": 0},
}  # fmt: skip


@pytest.fixture(scope="module")
def box_and_hand(tmp_path_factory):
    folder = tmp_path_factory.mktemp("hand_grasp")
    trimesh.creation.box((0.06, 0.05, 0.04)).export(folder / "box.obj")
    return folder / "box.obj", write_three_finger(folder)


def test_grasp_from_scratch_with_a_hand_from_its_mjcf(box_and_hand, tmp_path):
    box, xml = box_and_hand
    out = tmp_path / "out"
    code = main(["grasp", str(box), "--out", str(out), "--n", "4", "--threads", "1", "--hand", str(xml), "--from-scratch",
                 "--config-json", json.dumps(TINY)])  # fmt: skip
    every = read_grasp_store(out / "all_grasps.zarr")
    kept = read_grasp_store(out / "grasps.zarr")
    assert code in (0, 1) and len(every) == 4 and every.hand_pose.shape == (4, 15) and kept.hand_pose.shape[1] == 15
    for store in (every, kept):
        assert store.attrs["hand"] == str(xml) and len(store.attrs["hand_sha256"]) == 64
        assert store.attrs["joint_names"] == [f"{f}_j{k}" for f in ("f1", "f2", "th") for k in range(3)]
    assert {"lift_success", "six_dir_success", "failure_reason", "distinct_label"} <= set(every.arrays)
    assert len(list((out / "renders").glob("*.png"))) >= 1 and (out / "view.html").exists() == bool(len(kept))  # the hand's shapes drawn
    summary = (out / "summary.md").read_text()
    assert f"Hand: {xml} (9 joints" in summary and "draw its collision shapes" in summary
    if len(kept):
        assert json.loads((out / "dexgraspnet" / "hand.json").read_text())["joint_names"] == every.attrs["joint_names"]


def test_another_hand_refuses_the_shadow_hands_model_and_a_broken_mjcf_is_refused(box_and_hand, tmp_path, capsys):
    from dexlite_pipeline.model.shipped import SHIPPED_MODEL_PATH, shipped_model_path

    box, xml = box_and_hand
    base = ["grasp", str(box), "--out", str(tmp_path / "out"), "--n", "2"]
    error = one_line_cli_error(capsys, [*base, "--hand", "allegro", "--model", str(SHIPPED_MODEL_PATH)])  # the Shadow Hand's model
    assert f"--model {SHIPPED_MODEL_PATH}: a model of hand shadow, this run's hand is allegro" in error and "--from-scratch" in error
    error = one_line_cli_error(capsys, [*base, "--hand", str(xml)])  # no --model: none ships for a hand from its file
    shipped = ", ".join(hand for hand in ("shadow", "allegro", "leap") if shipped_model_path(hand) is not None)
    assert f"no model ships for hand {xml} (shipped models: {shipped}): pass --model FILE or --from-scratch" in error
    broken = tmp_path / "broken.xml"
    broken.write_text("<mujoco><worldbody><body name='palm'><geom type='box' size='0.1 0.1 0.1'/></body></worldbody></mujoco>")
    assert f"hand: {broken}: the model has no joints" in one_line_cli_error(capsys, [*base, "--hand", str(broken), "--from-scratch"])
    assert "hand: nothere.xml: no such file" in one_line_cli_error(capsys, [*base, "--hand", "nothere.xml", "--from-scratch"])
    error = one_line_cli_error(capsys, [*base, "--hand", str(xml), "--from-scratch", "--grasp-type", "pinch"])
    assert f"hand: {xml}: hand three_finger: grasp type pinch is not defined for this hand (it offers power)" in error
    assert not (tmp_path / "out").exists()


def test_grasp_with_a_model_for_a_hand_from_its_mjcf(box_and_hand, tmp_path, capsys):
    """--hand with --model and --evaluator made for that hand: samples of 6 + 9 numbers, ranked and refined with its own
    energies, lift-tested in its own scene; the Shadow Hand's run refuses the same files in one line each."""
    box, xml = box_and_hand
    model, evaluator = untrained_model_and_evaluator(tmp_path, str(xml))
    out = tmp_path / "with_model"
    config = {**TINY, "post_optimize": {"annealing": {"iterations": 10}}, "evaluator": {"pool_factor": 2}}
    code = main(["grasp", str(box), "--out", str(out), "--n", "2", "--threads", "1", "--hand", str(xml), "--model", str(model),
                 "--evaluator", str(evaluator), "--min-distinct", "0", "--config-json", json.dumps(config)])  # fmt: skip
    every = read_grasp_store(out / "all_grasps.zarr")
    assert code in (0, 1) and every.hand_pose.shape == (2, 15) and set(every.arrays["method"]) == {"cvae_post"}
    assert every.arrays["raw_hand_pose"].shape == (2, 15) and np.isfinite(every.hand_pose).all()
    assert ((every.arrays["evaluator_score"] > 0) & (every.arrays["evaluator_score"] < 1)).all()
    assert every.attrs["hand"] == str(xml) and {"lift_success", "six_dir_success"} <= set(every.arrays)

    base = ["grasp", str(box), "--out", str(tmp_path / "refused"), "--n", "2"]
    error = one_line_cli_error(capsys, [*base, "--model", str(model), "--no-evaluator"])
    assert f"--model {model}: a model of hand {xml}, this run's hand is shadow" in error
    (tmp_path / "shadow").mkdir()
    shadow_model = untrained_model_and_evaluator(tmp_path / "shadow", "shadow")[0]
    error = one_line_cli_error(capsys, [*base, "--hand", str(xml), "--model", str(shadow_model), "--evaluator", str(evaluator)])
    assert f"--model {shadow_model}: a model of hand shadow, this run's hand is {xml}" in error
    error = one_line_cli_error(capsys, [*base, "--model", str(shadow_model), "--evaluator", str(evaluator)])
    assert f"--evaluator {evaluator}: a grasp evaluator of hand {xml}, this run's hand is shadow" in error
    assert not (tmp_path / "refused").exists()


def test_api_grasp_with_a_hand_names_its_joints(box_and_hand):
    from dexlite_pipeline.api import grasp

    box, xml = box_and_hand
    result = grasp([str(box)], n=2, from_scratch=True, hand=str(xml), config=TINY)
    mesh = result.meshes["user-box"]
    assert mesh.joint_names == tuple(f"{f}_j{k}" for f in ("f1", "f2", "th") for k in range(3)) and mesh.hand_pose.shape[1] == 15
    assert mesh.attempts == 2


def test_distinct_grasps_of_any_hand_are_told_apart_by_the_palm_alone():
    import numpy as np

    from dexlite_pipeline.evaluation.diversity import distinct_grasp_labels

    poses = np.zeros((3, 15))
    poses[1, 6:] = 1.0  # same palm, other joints: the same grasp
    poses[2, 0] = 0.05  # palm 5 cm away: another
    assert distinct_grasp_labels(poses).tolist() == [0, 0, 1]
    assert distinct_grasp_labels(np.zeros(28)).tolist() == [0]  # one Shadow Hand pose, flat
