"""Grasp-like hand poses built in closed form, for the model and optimizer tests and the timing benchmarks (not training data).

The object's centre is put in front of the palm (palm frame −y, where the finger pads
face), just off the palm for an object of radius ``scale``, with the fingers half closed
and a random palm orientation. Such poses touch or slightly penetrate the object, like a
CVAE sample does, so optimizer timings and energy checks run where hands meet objects.
"""

from __future__ import annotations

import numpy as np
import torch

from dexlite_pipeline.hand.model import ShadowHand
from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix, matrix_to_euler_xyz
from dexlite_pipeline.io.grasp_store import GraspSet


def facing_grasps(hand: ShadowHand, object_ids, count: int, seed: int, scales=(0.06, 0.08, 0.1)) -> GraspSet:
    """``count`` poses dealt over ``object_ids`` in turn, scales drawn from ``scales`` (seeded)."""
    rng = np.random.default_rng(seed)
    scale = rng.choice(np.asarray(scales, np.float32), count)
    rotation = euler_xyz_to_matrix(torch.as_tensor(rng.uniform(-np.pi, np.pi, (count, 3)), dtype=torch.float32))
    centre_in_palm = torch.stack(
        [torch.full((count,), 0.01), -(torch.as_tensor(scale) + 0.015), torch.full((count,), 0.07)], dim=1
    )
    translation = -(rotation @ centre_in_palm[:, :, None])[:, :, 0]
    limits = hand.joint_limits.cpu()
    fraction = torch.as_tensor(rng.uniform(0.3, 0.5, (count, limits.shape[0])), dtype=torch.float32)
    joints = limits[:, 0] + (limits[:, 1] - limits[:, 0]) * fraction
    pose = torch.cat([translation, matrix_to_euler_xyz(rotation), joints], dim=1).numpy()
    objects = np.asarray([object_ids[i % len(object_ids)] for i in range(count)], dtype=object)
    return GraspSet({"hand_pose": pose, "object_id": objects, "scale": scale})
