"""The table frame the generator reads and writes grasps in: each object's own frame turned so its table's upward
normal is +z.

An object rests on the table in the pose the stability stage found, which for a file in an arbitrary orientation (a
scan saved y-up, a procedural object that topples) puts the table on any side of the object frame. The generator has
no table input: it learns where the table is from the cloud's orientation, so every cloud it reads, in training and
in sampling, is turned into the table frame (``upright_rotation``: the smallest rotation taking the support normal to
+z), the grasps with it, and the decoded grasps are turned back into the object's frame before the energies, the
stores and the simulator see them. For an object standing as in its file (the generated families) the rotation is
the identity to within the settling's 1e-4; without a table (floating mode) it is the identity. The learned evaluator
keeps the object frame: it reads the table as an input of its own.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from dexlite_pipeline.model.pose import rotate_features

UP = np.array([0.0, 0.0, 1.0])


def upright_rotation(normal) -> np.ndarray:
    """(3, 3) the smallest rotation R with R @ normal = +z (``normal`` the table's upward normal in the object frame);
    the identity for a non-finite or zero normal (no table); a half turn about x for a normal pointing along -z."""
    n = np.asarray(normal, dtype=np.float64).reshape(3)
    length = float(np.linalg.norm(n)) if np.isfinite(n).all() else 0.0
    if length == 0.0:
        return np.eye(3)
    n = n / length
    axis = np.cross(n, UP)
    sine, cosine = float(np.linalg.norm(axis)), float(n @ UP)
    if sine < 1e-12:
        return np.eye(3) if cosine > 0 else np.diag([1.0, -1.0, -1.0])
    k = axis / sine
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    angle = math.atan2(sine, cosine)
    return np.eye(3) + math.sin(angle) * cross + (1.0 - math.cos(angle)) * (cross @ cross)


def upright_rotations(object_ids: list[str], planes=None, device: torch.device | str = "cpu") -> torch.Tensor:
    """(O, 3, 3) float32 ``upright_rotation`` of each object's support plane in ``planes`` (a ``tabletop.SupportPlanes``
    or None); the identity for objects it does not hold and without planes."""
    held = getattr(planes, "planes", None) or {}
    rotations = [upright_rotation(held[oid].normal) if oid in held else np.eye(3) for oid in object_ids]
    stacked = np.stack(rotations) if rotations else np.zeros((0, 3, 3))
    return torch.as_tensor(stacked, dtype=torch.float32, device=device)


def no_turn(rotation: torch.Tensor) -> bool:
    """Whether every rotation (N, 3, 3) is exactly the identity: the helpers below then return their input as it is
    (floating mode and objects standing as in their files give the same numbers, bit for bit, as without the frame)."""
    return bool((rotation == torch.eye(3, dtype=rotation.dtype, device=rotation.device)).all())


def rotate_clouds(clouds: torch.Tensor, rotation: torch.Tensor) -> torch.Tensor:
    """Clouds (C, P, 6: points, normals) turned by ``rotation`` (C, 3, 3)."""
    if no_turn(rotation):
        return clouds
    turn = rotation.to(clouds.dtype).transpose(1, 2)
    return torch.cat([clouds[..., :3] @ turn, clouds[..., 3:] @ turn], dim=2)


def rotate_vectors(vectors: torch.Tensor, rotation: torch.Tensor) -> torch.Tensor:
    """Vectors (B, 3) turned by ``rotation`` (B, 3, 3)."""
    if no_turn(rotation):
        return vectors
    return (rotation.to(vectors.dtype) @ vectors[..., None])[..., 0]


def rotate_grasps(features: torch.Tensor, rotation: torch.Tensor) -> torch.Tensor:
    """Grasp features (B, 9 + J) of objects turned by ``rotation`` (B, 3, 3) (``pose.rotate_features``)."""
    return features if no_turn(rotation) else rotate_features(features, rotation)
