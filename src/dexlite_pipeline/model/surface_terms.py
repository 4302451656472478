"""Loss terms read off the training clouds' surface samples, with no SDF grid or mesh per object.

The generator's decoded hands miss the surface by millimetres: a held-out object's raw samples start a median of about
1 cm inside it, so four in five fail the lift test's 2 mm start cap before any push, and most of the rest hover. The
mesh-based energies (``train.energy_weights``) would score that, but cost about 46 MB an object, too much for a dataset
of 1,500 objects. These terms need only what training already holds: each object's surface samples and their outward
normals (``ObjectClouds.surface``, ``.normals``, area-uniform, 4,096 by default). Per decoded grasp:

- ``surface_pen`` (metres), the penetration: object in hand, Σ over the object's samples (at the grasp's scale) of
  max(0, d_hand(p)), where d_hand is the hand's collision shapes' analytic signed distance (positive inside), times
  2,000 / samples, so the sum reads as over 2,000 points as DexGraspNet's E_pen does; plus hand in object, Σ over the
  hand's penetration keypoints (points on the finger capsules' axes and the palm box) of max(0, -(k - p)·n), p and n
  the nearest sample and its outward normal: the depth of k below the tangent plane at the nearest surface sample,
  which is the signed distance wherever the surface is smooth on the scale of the sample spacing (a few mm); it sees
  a finger buried wholly inside, which the first sum cannot.
- ``surface_dis`` (cm²), the contact geometry of the training grasp, reproduced: for each of the hand's contact
  candidates (points on the finger pads) within ``CONTACT_BAND_M`` of the surface in the training grasp, its height
  over the tangent plane at the sample nearest it in the training grasp, decoded against trained; the mean squared
  difference in cm. Both too deep and too far count, so it asks the decoder for what a grasp that holds needs, pads
  on the surface, where the pose's squared error weighs a millimetre at a fingertip no more than one at the wrist.

Which samples lie inside the hand, and the nearest samples, are found without gradient, in chunks of grasps, so memory
stays near ``NEAREST_CHUNK_ELEMENTS`` floats whatever the batch size; the depths and heights are then evaluated with
gradient for those samples only (a few dozen a grasp), which keeps the backward pass small. ``surface_dis``'s search
(the sample nearest each pad point of the training grasp, 140 points against 4,096 samples) depends on the training
grasp only, not on the model: given the number of training grasps, the terms keep each grasp's nearest samples from its
first batch on (4 bytes a pad point, ~34 MB for 60,000 grasps), which takes the search out of every later epoch (it was
~90% of the term's cost, ~0.13 CPU-s a 64-grasp step).
"""

from __future__ import annotations

from collections.abc import Callable

import torch

from dexlite_pipeline.hand.model import CAPSULE, box_signed_distance, capsule_signed_distance
from dexlite_pipeline.model.config import SURFACE_DISTANCE_TERM, SURFACE_PENETRATION_TERM, SURFACE_TERMS
from dexlite_pipeline.model.data import ObjectClouds

REFERENCE_SAMPLES = 2000  # the object-in-hand sum reads as over this many samples (DexGraspNet's E_pen point count)
NEAREST_CHUNK_ELEMENTS = 8_000_000  # distances computed at once in the searches without gradient (32 MB of float32)

CONTACT_BAND_M = 0.01  # surface_dis: the training grasp's pad points within this of the surface (both ways) are matched

# (palm_rot (B,3,3), palm_t (B,3), joints (B,J), object_index (B,), scale (B,), target: the training grasps' (palm_rot,
# palm_t, joints)) -> {term: (B,)}, the decoded poses and targets in the object's frame
SurfaceTerms = Callable[..., dict[str, torch.Tensor]]


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


def penetration(hand, frames, samples: torch.Tensor, normals: torch.Tensor) -> torch.Tensor:
    """``surface_pen`` of hands at ``frames`` (B grasps) on their objects' ``samples`` and ``normals`` (B, Q, 3; metres,
    object frame): (B,) metres."""
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


def contact_heights(
    hand, frames, target_points: torch.Tensor, samples: torch.Tensor, normals: torch.Tensor, nearest: torch.Tensor | None = None
) -> torch.Tensor:
    """``surface_dis`` of hands at ``frames`` against their training grasps, whose pad points (``contact_candidates``)
    are ``target_points`` (B, C, 3), on the objects' ``samples`` and ``normals`` (B, Q, 3): (B,) cm², 0 for a grasp with
    no pad point in the band. ``nearest`` (B, C): the index of the sample nearest each of those C points, when known
    (else searched)."""
    with torch.no_grad():
        if nearest is None:
            nearest = nearest_sample_index(target_points, samples)
        rows = torch.arange(len(samples), device=samples.device)[:, None]
        plane_point, plane_normal = samples[rows, nearest], normals[rows, nearest]
        target_height = ((target_points - plane_point) * plane_normal).sum(dim=2)
        band = (target_height.abs() < CONTACT_BAND_M).to(samples.dtype)
    height = ((hand.contact_candidates(frames) - plane_point) * plane_normal).sum(dim=2)
    squared = ((height - target_height) / 0.01).square() * band
    return squared.sum(dim=1) / band.sum(dim=1).clamp(min=1)


class TrainingGraspNearest:
    """Per training grasp, the index of the surface sample nearest each of its pad points (``contact_candidates``), filled
    the first time a batch holds the grasp (-1 until then). Exact: the search reads only the training grasp and its
    object's samples in the object's frame, which no training step changes."""

    def __init__(self, grasp_count: int, pad_points: int) -> None:
        self.index = torch.full((grasp_count, pad_points), -1, dtype=torch.int32)

    def lookup(self, grasp_index: torch.Tensor, target_points: torch.Tensor, samples: torch.Tensor) -> torch.Tensor:
        """(B, C) nearest-sample indices of the grasps ``grasp_index`` (B,), whose pad points are ``target_points``
        (B, C, 3) on ``samples`` (B, Q, 3); searched for the grasps not seen before."""
        rows = grasp_index.cpu()
        known = self.index[rows]
        missing = (known[:, 0] < 0).nonzero()[:, 0]
        if len(missing):
            found = nearest_sample_index(target_points[missing.to(target_points.device)], samples[missing.to(samples.device)])
            known[missing] = found.cpu().to(torch.int32)
            self.index[rows[missing]] = known[missing]
        return known.to(device=samples.device, dtype=torch.long)


def surface_terms(hand, clouds: ObjectClouds, names: tuple[str, ...], training_grasps: int = 0) -> SurfaceTerms:
    """The terms ``names`` (of ``model.config.SURFACE_TERMS``) for decoded poses of the objects of ``clouds``. With
    ``training_grasps`` (the number of training grasps), calls that pass ``grasp_index`` (B,: which training grasps the
    targets are) reuse each grasp's nearest samples for ``surface_dis`` (``TrainingGraspNearest``)."""
    unknown = set(names) - set(SURFACE_TERMS)
    if unknown:
        raise ValueError(f"unknown surface terms {sorted(unknown)}")
    cache = None
    if training_grasps > 0 and SURFACE_DISTANCE_TERM in names:
        cache = TrainingGraspNearest(training_grasps, len(hand.contact_points_local))

    def terms(palm_rot, palm_t, joints, object_index, scale, target, grasp_index=None):
        frames = hand.forward_parts(palm_rot, palm_t, joints)
        samples = clouds.surface[object_index] * scale[:, None, None]  # (B, Q, 3) metres, object frame
        normals = clouds.normals[object_index]
        out = {}
        if SURFACE_PENETRATION_TERM in names:
            out[SURFACE_PENETRATION_TERM] = penetration(hand, frames, samples, normals)
        if SURFACE_DISTANCE_TERM in names:
            with torch.no_grad():
                target_points = hand.contact_candidates(hand.forward_parts(*target))  # (B, C, 3)
                nearest = None
                if cache is not None and grasp_index is not None:
                    nearest = cache.lookup(grasp_index, target_points, samples)
            out[SURFACE_DISTANCE_TERM] = contact_heights(hand, frames, target_points, samples, normals, nearest)
        return out

    return terms
