"""A penetration loss term read off the training clouds' surface samples, with no SDF grid or mesh per object.

The generator's decoded hands start inside the object more often than not (a held-out object's raw samples: median
about 1 cm deep, so four in five fail the lift test's 2 mm start cap before any push), and the mesh-based energies
(``train.energy_weights``) cost about 46 MB an object, too much for a dataset of 1,500 objects. This term needs only
what training already holds: each object's surface samples and their outward normals (``ObjectClouds.surface``,
``.normals``, area-uniform, 4,096 by default). Per decoded grasp, in metres:

- object in hand: Σ over the object's samples (at the grasp's scale) of max(0, d_hand(p)), where d_hand is the hand's
  collision shapes' analytic signed distance (positive inside), times 2,000 / samples, so the sum reads as over 2,000
  points as DexGraspNet's E_pen does;
- hand in object: Σ over the hand's penetration keypoints (points on the finger capsules' axes and the palm box) of
  max(0, -(k - p)·n), p and n the nearest sample and its outward normal: the depth of k below the tangent plane at
  the nearest surface sample, which is the signed distance wherever the surface is smooth on the scale of the
  sample spacing (a few mm); it sees a finger buried wholly inside, which the first sum cannot.

Which samples lie inside the hand, and each keypoint's nearest sample, are found without gradient, in chunks of grasps,
so memory stays near ``NEAREST_CHUNK_ELEMENTS`` floats whatever the batch size; the depths are then evaluated with
gradient for those samples only (a few dozen a grasp), which keeps the backward pass small.
"""

from __future__ import annotations

from collections.abc import Callable

import torch

from dexlite_pipeline.hand.model import CAPSULE, box_signed_distance, capsule_signed_distance
from dexlite_pipeline.model.data import ObjectClouds

REFERENCE_SAMPLES = 2000  # the object-in-hand sum reads as over this many samples (DexGraspNet's E_pen point count)
NEAREST_CHUNK_ELEMENTS = 8_000_000  # distances computed at once in the searches without gradient (32 MB of float32)

# (palm_rot (B,3,3), palm_t (B,3), joints (B,J), object_index (B,), scale (B,)) -> (B,) metres
SurfacePenetration = Callable[[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor], torch.Tensor]


def nearest_sample_index(points: torch.Tensor, samples: torch.Tensor) -> torch.Tensor:
    """(B, K) index of the nearest of ``samples`` (B, Q, 3) to each of ``points`` (B, K, 3), without gradient."""
    with torch.no_grad():
        per_grasp = max(1, NEAREST_CHUNK_ELEMENTS // max(1, points.shape[1] * samples.shape[1]))
        parts = [torch.cdist(points[i:i + per_grasp], samples[i:i + per_grasp]).argmin(dim=2)
                 for i in range(0, points.shape[0], per_grasp)]  # fmt: skip
        return torch.cat(parts) if parts else torch.zeros(points.shape[:2], dtype=torch.long, device=points.device)


def _depths(hand, rot: torch.Tensor, centre: torch.Tensor, points: torch.Tensor) -> torch.Tensor:
    """Signed distance (positive inside) of ``points`` (N, P, 3) to the union of the hand's collision shapes, whose
    rotations (N, S, 3, 3) and centres (N, S, 3) are given per row: (N, P)."""
    local = torch.matmul(points[:, None, :, :] - centre[:, :, None, :], rot)  # (N, S, P, 3): R^T (x - c), as rows
    size = hand.shape_size
    capsules, boxes = hand.capsule_ids, hand.box_ids
    inside = [capsule_signed_distance(local[:, capsules], size[capsules, 0][None, :, None], size[capsules, 1][None, :, None])]
    if len(boxes):
        inside.append(box_signed_distance(local[:, boxes], size[boxes][None, :, None, :]))
    return torch.cat(inside, dim=1).max(dim=1).values


def samples_inside_hand(hand, rot: torch.Tensor, centre: torch.Tensor, samples: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(grasp, sample) index pairs of the ``samples`` (B, Q, 3) inside the hand's collision shapes (rotations (B, S, 3, 3),
    centres (B, S, 3)), found without gradient: a sample is tested against a shape only when it lies within the shape's
    bounding sphere (one batched product gives every squared distance to the shapes' centres)."""
    with torch.no_grad():
        size = hand.shape_size
        bound = torch.where(hand.shape_kind == CAPSULE, size[:, 0] + size[:, 1], size.norm(dim=1))  # (S,) bounding radii
        squared = (samples.square().sum(-1)[:, :, None] - 2 * torch.bmm(samples, centre.transpose(1, 2))
                   + centre.square().sum(-1)[:, None, :])  # (B, Q, S)
        grasp, sample, shape = torch.nonzero(squared < bound.square()[None, None, :], as_tuple=True)
        local = ((samples[grasp, sample] - centre[grasp, shape])[:, None, :] @ rot[grasp, shape])[:, 0]  # (M, 3)
        depth = torch.where(hand.shape_kind[shape] == CAPSULE,
                            capsule_signed_distance(local, size[shape, 0], size[shape, 1]), box_signed_distance(local, size[shape]))
        inside = torch.unique(grasp[depth > 0] * samples.shape[1] + sample[depth > 0])
        return inside // samples.shape[1], inside % samples.shape[1]


def surface_penetration_terms(hand, clouds: ObjectClouds) -> SurfacePenetration:
    """The loss term above for decoded poses (object frame) of the objects of ``clouds``, with ``hand``'s shapes."""

    def term(palm_rot, palm_t, joints, object_index, scale):
        frames = hand.forward_parts(palm_rot, palm_t, joints)
        samples = clouds.surface[object_index] * scale[:, None, None]  # (B, Q, 3) metres, object frame
        normals = clouds.normals[object_index]
        rot, centre = hand.shape_frames(frames)
        # object in hand: the few samples inside, found without gradient, then their depths again with it
        grasp, sample = samples_inside_hand(hand, rot.detach(), centre.detach(), samples)
        depth = _depths(hand, rot[grasp], centre[grasp], samples[grasp, sample][:, None, :])[:, 0].clamp(min=0)
        object_in_hand = torch.zeros(len(samples), dtype=depth.dtype, device=depth.device).index_add(0, grasp, depth)
        object_in_hand = object_in_hand * (REFERENCE_SAMPLES / samples.shape[1])
        # hand in object: the keypoints' depths below the tangent plane at their nearest sample
        keypoints = hand.penetration_keypoints(frames)  # (B, K, 3)
        nearest = nearest_sample_index(keypoints, samples)
        rows = torch.arange(len(keypoints), device=keypoints.device)[:, None]
        below = ((samples[rows, nearest] - keypoints) * normals[rows, nearest]).sum(dim=2)  # > 0: under the tangent plane
        return object_in_hand + below.clamp(min=0).sum(dim=1)

    return term
