"""Random hand poses for the kinematics tests."""

import numpy as np


def random_poses(hand, count: int, seed: int) -> np.ndarray:
    """(count, 28) poses: palm within ~0.2 m of the origin in any orientation, joints uniform within their limits."""
    rng = np.random.default_rng(seed)
    limits = hand.joint_limits.numpy().astype(np.float64)
    pose = np.zeros((count, 28))
    pose[:, :3] = rng.normal(scale=0.2, size=(count, 3))
    pose[:, 3:6] = rng.uniform(-np.pi, np.pi, size=(count, 3))
    pose[:, 6:] = rng.uniform(limits[:, 0], limits[:, 1], size=(count, 22))
    return pose
