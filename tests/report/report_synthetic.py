"""Synthetic grasp stores shaped like the evaluation's inputs and outputs (for tests/report)."""

import numpy as np

from dexlite_pipeline.io.grasp_store import GraspSet, write_grasp_store

OBJECT_ID = "tiny_box"


def grasp_poses(n: int, rng: np.random.Generator) -> np.ndarray:
    """Palm 9 cm above the object centre, facing down (-z), fingers half closed with some spread."""
    pose = np.zeros((n, 28), np.float32)
    pose[:, 2] = 0.09
    pose[:, 3] = np.pi  # rotate about x: palm normal points down
    pose[:, 6:] = rng.uniform(0.1, 0.6, size=(n, 22))
    return pose


def simulated_shard(path, methods_success: dict[str, list[bool]], rng, attrs=None):
    """A store shaped like evaluate's simulated output, with chosen lift outcomes per method."""
    methods, success = [], []
    for method, flags in methods_success.items():
        methods += [method] * len(flags)
        success += flags
    n = len(methods)
    arrays = {
        "hand_pose": grasp_poses(n, rng),
        "object_id": np.full(n, OBJECT_ID, dtype=object),
        "scale": np.full(n, 0.06, np.float32),
        "method": np.asarray(methods, dtype=object),
        "split": np.full(n, "heldout", dtype=object),
        "source_row": np.arange(n),
        "lift_success": np.asarray(success, dtype=bool),
        "six_dir_success": np.zeros(n, bool),
        "failure_reason": np.where(success, "", "object slipped").astype(object),
        "penetration_mm": rng.uniform(0, 2, n).astype(np.float32),
        "contact_distance_mm": rng.uniform(0, 3, n).astype(np.float32),
        "E_fc": rng.uniform(0, 1, n).astype(np.float32),
        "E_dis": np.full(n, 0.002, np.float32),
        "E_pen": np.zeros(n, np.float32),
    }
    write_grasp_store(path, GraspSet(arrays), attrs or {})
    return path


def post_store(path, n: int, iterations: int, rng, decay: float):
    """A post-optimization store whose E_fc trace falls below 0.3 at a known iteration."""
    t = np.arange(iterations)
    e_fc = np.tile(np.exp(-decay * t)[None], (n, 1))
    arrays = {
        "hand_pose": grasp_poses(n, rng),
        "object_id": np.full(n, OBJECT_ID, dtype=object),
        "scale": np.full(n, 0.06, np.float32),
        "trace_E_post": e_fc + 0.1,
        "trace_E_fc": e_fc,
        "trace_E_dis": np.full((n, iterations), 0.001),
        "trace_E_pen": np.zeros((n, iterations)),
    }
    write_grasp_store(path, GraspSet(arrays), {"trace_iterations": (t * 10).tolist(), "seconds_per_grasp": 0.5})
    return path
