"""The Shadow Hand's model path gives the same numbers, bit for bit, as before the model stages learned other hands.

The shipped model (a Shadow Hand model written before checkpoints recorded their hand) samples, reconstructs and is
scored by the shipped evaluator on two synthetic objects with fixed seeds; the SHA-256 of every resulting float32
array must equal the digest computed with the code before that change (``EXPECTED_DIGESTS``), and a few of the
values are kept in clear so that a failure shows how far they moved. One torch thread, CPU.
"""

from __future__ import annotations

import hashlib
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from dexlite_pipeline.model.shipped import shipped_evaluator_path, shipped_model_path

OBJECT_SURFACE_SAMPLES = 600  # >= the shipped evaluator's 512 points per cloud
SYNTHESES_PER_OBJECT = 3
RECONSTRUCTED_GRASPS = 6

# sha256 of the float32 bytes of each array at the commit before hand-following model stages (5f4e6a8)
EXPECTED_DIGESTS = {
    "synthesized": "58dcf614075a60425da1d7f02427e5b124e57bb559fb8b1bc2372743c775c514",
    "ray_origin": "73c3ade2ea1da9b35027d1b141351be7fe8d1028ed5c609ec759ece92453fce8",
    "reconstructed": "01649778639840be2b1ed1827625953d751ba3aab372212bd882d6628dec0e8a",
    "held_probability": "8459414a3c737298204890c62556f4a5777ad4517e37a09c70f5d87ed9156129",
}
EXPECTED_FIRST_VALUES = {  # the first three numbers of each array, as printed at that commit (float32 -> repr)
    "synthesized": [0.0010272491490468383, 0.12619128823280334, 0.020072001963853836],
    "ray_origin": [-0.09027395397424698, -0.025232506915926933, -0.03881203383207321],
    "reconstructed": [-0.13208790123462677, -0.04398928955197334, -0.043171051889657974],
    "held_probability": [0.004426354076713324, 0.011328233405947685, 0.39314159750938416],
}


def synthetic_objects() -> list:
    """Two objects (an ellipsoid and a squashed cube's surface) as the assets ``ObjectClouds`` reads: normalized
    surface samples with outward normals, seeded."""
    rng = np.random.default_rng(20261205)
    directions = rng.normal(size=(OBJECT_SURFACE_SAMPLES, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    ellipsoid_axes = np.array([1.0, 0.7, 0.5])
    ellipsoid = directions * ellipsoid_axes
    ellipsoid_normals = directions / ellipsoid_axes
    cube = directions / np.abs(directions).max(axis=1, keepdims=True) * np.array([0.9, 0.9, 0.6])
    cube_normals = np.where(np.abs(directions) == np.abs(directions).max(axis=1, keepdims=True), np.sign(directions), 0.0)
    objects = []
    for object_id, points, normals in (("ellipsoid", ellipsoid, ellipsoid_normals), ("cube", cube, cube_normals)):
        normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
        objects.append(SimpleNamespace(object_id=object_id, real_scale=None, surface_points=points.astype(np.float32),
                                       surface_normals=normals.astype(np.float32)))
    return objects


def shadow_model_outputs() -> dict[str, np.ndarray]:
    """Samples, grasp rays, reconstructions and evaluator scores of the shipped (Shadow Hand) model, fixed seeds."""
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.model.association import grasp_rays
    from dexlite_pipeline.model.checkpoint import cloud_reading, load_checkpoint
    from dexlite_pipeline.model.config import SampleConfig
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.evaluator import load_evaluator, score_grasps
    from dexlite_pipeline.model.sampling import reconstruct, synthesis_rows

    model, checkpoint = load_checkpoint(shipped_model_path())
    points, fixed = cloud_reading(checkpoint)
    clouds = ObjectClouds(synthetic_objects())
    settings = SampleConfig(synthesis_grasps_per_object=SYNTHESES_PER_OBJECT, scales=(0.06, 0.08))
    rows = synthesis_rows(model, clouds, clouds.object_ids, settings, points, torch.Generator().manual_seed(7), fixed, "test")
    known = torch.as_tensor(checkpoint["training_grasps"]["hand_pose"][:RECONSTRUCTED_GRASPS], dtype=torch.float32)
    with torch.no_grad():
        origin, direction = grasp_rays(ShadowHand(), known)
    object_index = np.arange(RECONSTRUCTED_GRASPS) % 2
    scale = np.full(RECONSTRUCTED_GRASPS, 0.08, np.float32)
    reconstructed = reconstruct(model, clouds, known, origin, direction, object_index, scale, points, fixed, torch.Generator().manual_seed(8))
    evaluator, _ = load_evaluator(shipped_evaluator_path())
    held = score_grasps(evaluator, rows.hand_pose.numpy(), clouds, np.asarray(rows.object_id), rows.scale)
    return {
        "synthesized": rows.hand_pose.numpy(),
        "ray_origin": torch.cat([origin, direction], dim=1).numpy(),
        "reconstructed": reconstructed.numpy(),
        "held_probability": np.asarray(held),
    }


def digest(array: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(array, dtype=np.float32).tobytes()).hexdigest()


@pytest.mark.skipif(shipped_model_path() is None or shipped_evaluator_path() is None, reason="the package was installed without its data")
def test_the_shadow_hand_model_path_is_bit_for_bit_as_before():
    outputs = shadow_model_outputs()
    assert outputs["synthesized"].shape == (2 * SYNTHESES_PER_OBJECT, 28)
    first = {name: [float(v) for v in array.ravel()[:3]] for name, array in outputs.items()}
    assert first == EXPECTED_FIRST_VALUES
    assert {name: digest(array) for name, array in outputs.items()} == EXPECTED_DIGESTS


if __name__ == "__main__":  # print the digests and first values (to fill in the expected ones)
    torch.set_num_threads(1)
    computed = shadow_model_outputs()
    print({name: digest(array) for name, array in computed.items()})
    print({name: [float(v) for v in array.ravel()[:3]] for name, array in computed.items()})
