"""One ``GraspSimulator`` serves every grasp of an object (``sim.lift`` caches one per object, scale and table), so a
grasp's outcome must not depend on what that simulator ran before: each test resets MuJoCo's data, and the six
pushes switch gravity and the table's contacts off and restore them.

The grasps are the square bar's hook grasp (held), the same 5 mm to the side, and the same 10 cm away (dropped,
extrapolated once out of reach); floating and on a table.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from bar_grasps import SCALE

from dexlite_pipeline.objects.assets import SdfBank, load_asset
from dexlite_pipeline.objects.rest_pose import SupportPlane
from dexlite_pipeline.sim.config import LiftConfig
from dexlite_pipeline.sim.scene import LiftScene
from dexlite_pipeline.sim.simulator import GraspSimulator, _palm_quaternions
from dexlite_pipeline.sim.squeeze import squeeze_targets

STANDING = SupportPlane((1.0, 0.0, 0.0), 1.0)  # the square bar standing on its end


def _cases(hand, asset, hook: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """(pose, squeeze target) of the three grasps, float64 as ``sim.lift`` passes them."""
    side, away = hook.copy(), hook.copy()
    side[1] += 0.005
    away[2] += 0.10
    poses = np.stack([hook, side, away]).astype(np.float64)
    targets = squeeze_targets(hand, SdfBank([asset]), torch.as_tensor(poses, dtype=hand.dtype), torch.full((3,), SCALE, dtype=hand.dtype),
                              LiftConfig()).targets
    return list(zip(poses, targets.numpy().astype(np.float64)))


def _run(sim: GraspSimulator, pose: np.ndarray, target: np.ndarray) -> dict:
    """Every number one grasp's tests give, and MuJoCo's state (qpos, qvel) after the lift and after the pushes."""
    d = sim.scene.data
    quat = _palm_quaternions(pose[None])[0]
    out = {"overlap": sim.initial_contact_depth_m(pose, quat)}
    out["ratio"], out["reason"] = sim.lift(pose, quat, target)
    out["lifted"] = np.concatenate([d.qpos, d.qvel])
    out["translation"], out["rotation"] = sim.six_directions(pose, quat, target)
    out["pushed"] = np.concatenate([d.qpos, d.qvel])
    return out


@pytest.mark.parametrize("table", [None, STANDING], ids=["floating", "table"])
def test_reused_simulator_gives_a_fresh_ones_outcomes_bit_for_bit_in_any_order(hand, objects_dir, hooks, table):
    config = LiftConfig(six_directions=True, six_dir_exhaustive=True)
    asset = load_asset(objects_dir, "square_bar")
    cases = _cases(hand, asset, hooks["square_bar"])

    def simulator() -> GraspSimulator:
        return GraspSimulator(LiftScene.build(asset.convex_paths, SCALE, config, table), config)

    fresh = [_run(simulator(), *case) for case in cases]
    assert [r["reason"] for r in fresh] == ["", "", "dropped"]  # held, held, dropped: both paths of the lift
    shared = simulator()
    gravity = shared.scene.model.opt.gravity.copy()
    for order in ([2, 1, 0], [1, 0, 2, 0]):
        for i in order:
            again = _run(shared, *cases[i])
            for key, value in fresh[i].items():
                np.testing.assert_array_equal(again[key], value, err_msg=f"grasp {i}, {key}, order {order}")
    np.testing.assert_array_equal(shared.scene.model.opt.gravity, gravity)
    if table is not None:
        assert shared.scene.model.geom_contype[shared.scene.table_geom] == 1 == shared.scene.model.geom_conaffinity[shared.scene.table_geom]
