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


def simulated_shard(path, methods_success: dict[str, list[bool | None]], rng, attrs=None):
    """A store shaped like evaluate's simulated output, with chosen lift outcomes per method.

    An outcome of None is an invalid grasp: NaN pose, not simulated (NaN measurements), a failure.
    """
    methods, outcomes = [], []
    for method, flags in methods_success.items():
        methods += [method] * len(flags)
        outcomes += flags
    n = len(methods)
    invalid = np.asarray([o is None for o in outcomes])
    success = np.asarray([bool(o) for o in outcomes])
    hand_pose = grasp_poses(n, rng)
    hand_pose[invalid] = np.nan

    def measured(values):
        return np.where(invalid, np.nan, values).astype(np.float32)

    arrays = {
        "hand_pose": hand_pose,
        "object_id": np.full(n, OBJECT_ID, dtype=object),
        "scale": np.full(n, 0.06, np.float32),
        "method": np.asarray(methods, dtype=object),
        "split": np.full(n, "heldout", dtype=object),
        "source_row": np.arange(n),
        "sample_row": np.full(n, -1),
        "invalid_reason": np.where(invalid, "non-finite hand_pose", "").astype(object),
        "lift_success": success,
        "six_dir_success": np.zeros(n, bool),
        "failure_reason": np.where(success, "", np.where(invalid, "invalid_grasp: non-finite hand_pose", "object slipped")).astype(object),
        "penetration_mm": measured(rng.uniform(0, 2, n)),
        "contact_distance_mm": measured(rng.uniform(0, 3, n)),
        "E_fc": measured(rng.uniform(0, 1, n)),
        "E_dis": measured(np.full(n, 0.002)),
        "filter_E_fc": measured(rng.uniform(0, 0.6, n)),  # the equal filter's energies (its own contact search)
        "filter_E_dis": measured(np.full(n, 0.002)),
        "E_pen": measured(np.zeros(n)),
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


def write_heldout_box(root):
    """One prepared object (a box, normalized size) under ``root``, with a catalog marking it held out; returns ``root``."""
    import pandas as pd
    import trimesh

    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    mesh = trimesh.creation.box(extents=(1.2, 0.8, 0.6))
    write_asset(mesh, OBJECT_ID, root, AssetBuildSettings(sdf_resolution=16, surface_points=128), {"source": "test"}, convex_pieces=[mesh])
    pd.DataFrame({"object_id": [OBJECT_ID, "train_obj"], "split": ["heldout", "train"], "status": ["ok", "ok"]}).to_parquet(root / "catalog.parquet")
    return root
