"""Honest controls of the MuJoCo lift test: good grasps pass, bad ones fail, for stated reasons.

The objects and the good grasps come from ``bar_grasps`` (fixtures in conftest.py): a
round and a square bar, each hooked by fingers flexed until they touch it.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from bar_grasps import JOINT, SCALE, grasp_set

from dexlite_pipeline.objects.assets import SdfBank, load_asset
from dexlite_pipeline.sim.config import LiftConfig
from dexlite_pipeline.sim.lift import run_lift_tests
from dexlite_pipeline.sim.simulator import DIRECTIONS
from dexlite_pipeline.sim.squeeze import squeeze_targets


def test_constructed_hook_grasp_touches_without_penetration(hand, objects_dir, hooks):
    for object_id, pose in hooks.items():
        asset = load_asset(objects_dir, object_id)
        flex = pose[6:][[JOINT["FFJ2"], JOINT["MFJ2"], JOINT["RFJ2"], JOINT["LFJ2"]]]
        assert (flex > 0.4).all() and (flex < 1.4).all(), f"{object_id}: fingers should wrap part way round the bar, got {flex}"
        plan = squeeze_targets(hand, SdfBank([asset]), torch.tensor(pose[None]), torch.tensor([SCALE]), LiftConfig())
        assert -0.003 < float(plan.hand_in_object_m[0]) < 0.0  # touching, not inside


def test_enclosing_grasp_passes_and_controls_fail(objects_dir, hooks):
    """Good grasp lifts; 10 cm away, fingers open, or a 50 kg object: dropped."""
    poses, ids, labels = [], [], []
    for object_id, pose in hooks.items():
        away = pose.copy()
        away[2] += 0.10  # palm 10 cm higher (the object frame's +z is the back of the hand)
        open_hand = pose.copy()
        open_hand[6:] = 0.0
        open_hand[6 + JOINT["THJ3"]] = 1.222
        poses += [pose, away, open_hand]
        ids += [object_id] * 3
        labels += [(object_id, "good"), (object_id, "away"), (object_id, "open")]
    grasps = grasp_set(poses, ids)
    result = run_lift_tests(grasps, [objects_dir], LiftConfig(), threads=1)
    outcome = {label: (float(r), str(reason)) for label, r, reason in zip(labels, result["lift_ratio"], result["failure_reason"])}
    for object_id in hooks:
        ratio, reason = outcome[(object_id, "good")]
        assert ratio > 0.9 and reason == "", (object_id, ratio, reason)
        for control in ("away", "open"):
            ratio, reason = outcome[(object_id, control)]
            assert ratio < 0.5 and reason == "dropped", (object_id, control, ratio, reason)
    assert result["lift_success"].tolist() == [True, False, False, True, False, False]

    heavy = run_lift_tests(grasp_set([hooks["round_bar"]], ["round_bar"]), [objects_dir], LiftConfig(object_mass_kg=50.0), threads=1)
    assert not heavy["lift_success"][0] and heavy["failure_reason"][0] == "dropped"
    assert heavy["lift_ratio"][0] < 0.5


def test_no_friction_squeezes_the_round_bar_out(objects_dir, hooks):
    """Friction matters: without it the squeeze pushes the round bar out of the open side of the hook."""
    result = run_lift_tests(grasp_set([hooks["round_bar"]], ["round_bar"]), [objects_dir], LiftConfig(friction=0.0), threads=1)
    assert not result["lift_success"][0]


def test_deep_initial_penetration_fails_before_simulation(objects_dir, hooks):
    buried = hooks["square_bar"].copy()
    buried[2] -= 0.03  # palm 3 cm down into the bar
    result = run_lift_tests(grasp_set([buried], ["square_bar"]), [objects_dir], LiftConfig(), threads=1)
    assert result["failure_reason"].tolist() == ["initial_penetration"]
    assert result["initial_penetration_mm"][0] > 10.0
    assert np.isnan(result["lift_ratio"][0]) and not result["lift_success"][0]


def test_squeeze_target_moves_only_touching_fingers_and_never_starts_there(hand, objects_dir, hooks):
    asset = load_asset(objects_dir, "round_bar")
    pose = torch.tensor(hooks["round_bar"][None])
    config = LiftConfig()
    target = squeeze_targets(hand, SdfBank([asset]), pose, torch.tensor([SCALE]), config).targets[0].numpy()
    delta = target - hooks["round_bar"][6:]
    for finger in ("FF", "MF", "RF", "LF"):
        ids = [i for name, i in JOINT.items() if name.startswith(finger)]
        assert np.abs(delta[ids]).max() == pytest.approx(config.squeeze_rad, rel=1e-4), finger
        assert delta[JOINT[f"{finger}J2"]] > 0  # flexing pushes the hooked finger into the bar
    thumb = [i for name, i in JOINT.items() if name.startswith("TH")]
    assert np.abs(delta[thumb]).max() == 0.0  # the folded thumb is far from the bar


def test_invalid_grasps_are_flagged_in_place_and_valid_ones_simulated(objects_dir, hooks):
    good = hooks["square_bar"]
    nan_pose = good.copy()
    nan_pose[4] = np.nan
    grasps = grasp_set([nan_pose, good, good], ["square_bar", "square_bar", "no_such_object"])
    result = run_lift_tests(grasps, [objects_dir], LiftConfig(), threads=1)
    assert result["failure_reason"].tolist() == [
        "invalid_grasp: non-finite hand_pose",
        "",
        "invalid_grasp: object id not in the object assets",
    ]
    assert result["lift_success"].tolist() == [False, True, False]
    assert np.isnan(result["lift_ratio"][[0, 2]]).all()


def test_grasps_known_to_fail_are_recorded_with_their_reason_and_not_simulated(objects_dir, hooks):
    good = hooks["square_bar"]
    grasps = grasp_set([good, good], ["square_bar", "square_bar"])
    result = run_lift_tests(grasps, [objects_dir], LiftConfig(), threads=1, known_failures=np.asarray(["", "optimization stopped early"], dtype=object))
    assert result["failure_reason"].tolist() == ["", "not_tested: optimization stopped early"]
    assert result["lift_success"].tolist() == [True, False]  # the same hook grasp holds when it is tested
    assert np.isfinite(result["lift_ratio"][0]) and np.isnan(result["lift_ratio"][1])


def test_six_directions_fail_open_hand_and_hold_gravity_direction_of_hook(objects_dir, hooks):
    open_hand = hooks["square_bar"].copy()
    open_hand[6:] = 0.0
    open_hand[6 + JOINT["THJ3"]] = 1.222  # the thumb clear of the bar: the grasp starts, and drops
    grasps = grasp_set([hooks["square_bar"], open_hand], ["square_bar", "square_bar"])
    result = run_lift_tests(grasps, [objects_dir], LiftConfig(six_directions=True, six_dir_exhaustive=True), threads=1)
    assert result["six_dir_translation_m"].shape == (2, 6) and result["six_dir_passed"].shape == (2, 6)
    down = DIRECTIONS.index("-z")
    assert result["six_dir_passed"][0, down]  # the hook holds the bar against a downward pull, like gravity
    assert not result["six_dir_success"][1]
    assert not result["six_dir_passed"][1].all()
    assert np.isfinite(result["six_dir_translation_m"]).all()  # exhaustive: every direction of every started grasp

    # By default only a grasp that lifted is pushed, up to its first failed direction: the same verdicts, fewer pushes.
    quick = run_lift_tests(grasps, [objects_dir], LiftConfig(six_directions=True), threads=1)
    assert quick["lift_success"].tolist() == [True, False] == result["lift_success"].tolist()
    assert np.isnan(quick["six_dir_translation_m"][1]).all() and not quick["six_dir_success"][1]
    assert quick["six_dir_success"][0] == result["six_dir_success"][0]
    failed = np.flatnonzero(~result["six_dir_passed"][0])
    pushed = 6 if len(failed) == 0 else failed[0] + 1
    np.testing.assert_array_equal(quick["six_dir_translation_m"][0, :pushed], result["six_dir_translation_m"][0, :pushed])
    assert np.isnan(quick["six_dir_translation_m"][0, pushed:]).all()


@pytest.mark.slow
def test_worker_threads_match_one_thread(objects_dir, hooks):
    """Two worker threads (one per object, each with its own scenes) give the same per-grasp results in input order."""
    grasps = grasp_set([hooks["square_bar"], hooks["round_bar"]], ["square_bar", "round_bar"])
    serial = run_lift_tests(grasps, [objects_dir], LiftConfig(), threads=1)
    pooled = run_lift_tests(grasps, [objects_dir], LiftConfig(), threads=2)
    np.testing.assert_array_equal(serial["lift_ratio"], pooled["lift_ratio"])
    assert serial["failure_reason"].tolist() == pooled["failure_reason"].tolist()


def test_config_rejects_nonsense():
    from dexlite_pipeline.config import ConfigError
    from dexlite_pipeline.sim.config import lift_config_from

    with pytest.raises(ConfigError, match="friction"):
        LiftConfig(friction=-1.0)
    with pytest.raises(ConfigError, match="unknown key"):
        lift_config_from({"lift": {"frction": 0.5}})
    assert lift_config_from({"lift": {"friction": 1.0}}, friction=None).friction == 1.0
    assert lift_config_from({}, friction=0.3).friction == 0.3


def test_configure_writes_constants_in_place_without_recompiling(objects_dir):
    import mujoco

    from dexlite_pipeline.sim.scene import LiftScene

    scene = LiftScene.build(load_asset(objects_dir, "square_bar").convex_paths, SCALE, LiftConfig())
    model = scene.model
    multi_ccd_off = int(mujoco.mjtDisableBit.mjDSBL_MULTICCD)
    assert model.body_mass[scene.object_body] == pytest.approx(0.1) and not model.opt.disableflags & multi_ccd_off
    inertia = model.body_inertia[scene.object_body].copy()
    scene.configure(LiftConfig(object_mass_kg=50.0, friction=1.0, finger_kp=2.0, multi_contact=False))
    assert model.body_mass[scene.object_body] == pytest.approx(50.0)
    np.testing.assert_allclose(model.body_inertia[scene.object_body], inertia * 500.0, rtol=1e-6)
    assert (model.geom_friction[scene.hand_geoms, 0] == 1.0).all() and (model.geom_friction[scene.object_geoms, 0] == 1.0).all()
    assert (model.actuator_gainprm[:, 0] == 2.0).all() and (model.actuator_biasprm[:, 1] == -2.0).all()
    assert model.opt.disableflags & multi_ccd_off
    scene.configure(LiftConfig())
    assert not model.opt.disableflags & multi_ccd_off and model.body_mass[scene.object_body] == pytest.approx(0.1)


@pytest.fixture
def simulated_steps(monkeypatch):
    """A list that grows by the number of MuJoCo steps of every ``mj_step`` call made while the test runs."""
    import mujoco

    steps = []
    mj_step = mujoco.mj_step

    def counting_step(m, d, nstep=1):
        steps.append(nstep)
        mj_step(m, d, nstep=nstep)

    monkeypatch.setattr(mujoco, "mj_step", counting_step)
    return steps


def test_settled_directions_stop_early_with_the_same_verdicts(objects_dir, hooks, simulated_steps):
    """A direction in which the grip has settled passes without its full two seconds: the same verdict per direction
    as with ``six_dir_settle_factor`` 0 (always the full duration), for far fewer steps."""
    steps = simulated_steps
    grasps = grasp_set([hooks["square_bar"]], ["square_bar"])
    verdicts, costs = [], []
    for factor in (0.0, LiftConfig().six_dir_settle_factor):
        steps.clear()
        result = run_lift_tests(grasps, [objects_dir], LiftConfig(six_directions=True, six_dir_exhaustive=True, six_dir_settle_factor=factor), threads=1)
        verdicts.append(result["six_dir_passed"][0].tolist())
        costs.append(sum(steps))
    assert verdicts[0] == verdicts[1] and any(verdicts[0])
    assert costs[1] < 0.7 * costs[0]


def test_lost_object_early_exit_matches_full_simulation_and_held_grasp_runs_every_step(hand, objects_dir, hooks, monkeypatch, simulated_steps):
    """A dropped object is extrapolated once provably out of reach (here while the fingers still close), giving
    the full simulation's ratio; a held object is simulated for the whole timeline."""
    from dexlite_pipeline.sim.scene import LiftScene
    from dexlite_pipeline.sim.simulator import GraspSimulator, _palm_quaternions

    config = LiftConfig()
    asset = load_asset(objects_dir, "square_bar")
    sim = GraspSimulator(LiftScene.build(asset.convex_paths, SCALE, config), config)
    steps = simulated_steps

    def lift(pose):
        steps.clear()
        target = squeeze_targets(hand, SdfBank([asset]), torch.as_tensor(pose[None], dtype=hand.dtype), torch.tensor([SCALE]), config).targets[0]
        ratio, reason = sim.lift(pose, _palm_quaternions(pose[None])[0], target.numpy().astype(np.float64))
        return ratio, reason, sum(steps)

    good = hooks["square_bar"].astype(np.float64)
    ratio, reason, simulated = lift(good)
    assert reason == "" and ratio > 0.9 and simulated == sim.total_steps == 1350

    away = good.copy()
    away[2] += 0.10
    early_ratio, early_reason, early_steps = lift(away)
    close_steps = sum(sim.close_chunks)
    assert early_reason == "dropped" and early_steps < close_steps  # lost before the fingers finished closing
    monkeypatch.setattr(sim, "_object_lost", lambda: False)
    full_ratio, full_reason, full_steps = lift(away)
    assert full_reason == "dropped" and full_steps == sim.total_steps
    assert early_ratio == pytest.approx(full_ratio, abs=1e-6)  # metres of the 1 m lift: equal to rounding


def test_preclose_adds_to_the_flexion_targets_only(hand, objects_dir, hooks):
    """The write-up's lenient protocol closes every finger's J2/J1/J0 a further preclose_rad; other joints keep the squeeze."""
    asset = load_asset(objects_dir, "round_bar")
    far = torch.tensor(hooks["round_bar"][None]).clone()
    far[0, :3] += 0.5  # nothing touches: the squeeze alone moves no joint
    strict = squeeze_targets(hand, SdfBank([asset]), far, torch.tensor([SCALE]), LiftConfig()).targets[0].numpy()
    lenient = squeeze_targets(hand, SdfBank([asset]), far, torch.tensor([SCALE]), LiftConfig(preclose_rad=0.07)).targets[0].numpy()
    np.testing.assert_allclose(strict, hooks["round_bar"][6:], atol=1e-6)
    limits = hand.joint_limits.cpu().numpy()
    for name, i in JOINT.items():
        flexion = name[:2] in ("FF", "MF", "RF", "LF") and name[-2:] in ("J2", "J1", "J0")
        expected = min(strict[i] + 0.07, limits[i, 1]) if flexion else strict[i]
        assert lenient[i] == pytest.approx(expected, abs=1e-6), name


def test_condim_reaches_the_object_geoms(objects_dir):
    from dexlite_pipeline.sim.scene import LiftScene

    asset = load_asset(objects_dir, "round_bar")
    scene = LiftScene.build(asset.convex_paths, SCALE, LiftConfig(contact_condim=6))
    assert set(scene.model.geom_condim[scene.object_geoms].tolist()) == {6}
    scene.configure(LiftConfig())  # a cached scene takes another config's condim in place
    assert set(scene.model.geom_condim[scene.object_geoms].tolist()) == {3}
    with pytest.raises(Exception, match="contact_condim"):
        LiftConfig(contact_condim=5)
