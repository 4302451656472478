"""Force closure of the contacts a grasp actually makes (Ferrari–Canny ε with friction cones).

DexGraspNet's E_fc scores four chosen contact candidates with unit normals and no
friction; an optimized grasp's four are picked after the fact, from many sets, as the ones
whose normals cancel best, so E_fc < 0.3 says little about how the hand really presses.
This module looks at the contacts instead: every hand link (finger segments and palm)
whose collision surface comes within ``contact_distance_m`` of the object contributes
one contact at its deepest surface point, with a Coulomb friction cone (``friction``,
linearized by ``cone_edges`` edges, each edge of unit normal component) about the
object's inward normal there. The wrenches are taken about the object frame's origin,
torques divided by the object's scale (≈ its radius in metres) so forces and torques
share a unit.

ε is the radius of the largest ball about the origin inside the convex hull of those
wrenches: the contacts resist every wrench of norm ε per newton of total normal force
(0 when the hull does not strictly contain the origin: no force closure). Why: failed
grasps mostly lose the object during the squeeze, before the lift, and the share lifted
rises with ε (docs/results.md, "Curation").
"""

from __future__ import annotations

import logging
import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import torch
from scipy.spatial import ConvexHull, QhullError

from dexlite_pipeline.hand.model import ShadowHand
from dexlite_pipeline.io.grasp_store import GraspSet, invalid_grasp_reasons
from dexlite_pipeline.objects.assets import ObjectAssetError, SdfBank, load_asset

log = logging.getLogger(__name__)

RANK_TOLERANCE = 1e-9  # singular values below this (wrench units) count as a missing direction


@dataclass(frozen=True)
class ContactModel:
    """Which hand links count as contacts and how much friction they have."""

    contact_distance_m: float = 0.001  # a link touches if its surface comes this close to the object
    friction: float = 0.6  # Coulomb coefficient of the friction cones
    cone_edges: int = 8  # edges of the linearized cones

    def __post_init__(self) -> None:
        if not self.contact_distance_m >= 0:
            raise ValueError(f"contact_distance_m must be >= 0, got {self.contact_distance_m}")
        if not self.friction >= 0:
            raise ValueError(f"friction must be >= 0, got {self.friction}")
        if self.cone_edges < 3:
            raise ValueError(f"cone_edges must be >= 3, got {self.cone_edges}")


def link_contacts(
    hand: ShadowHand, bank: SdfBank, hand_pose: torch.Tensor, object_index: torch.Tensor, scale: torch.Tensor, contact_distance_m: float
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Per grasp and hand link: deepest surface point (B, L, 3), the object's outward normal there (B, L, 3), touching mask (B, L).

    Links without collision shapes never touch.
    """
    with torch.no_grad():
        points = hand.surface_points(hand.forward(hand_pose))
        distance, normal = bank.signed_distance(points, object_index, scale)
    link_count = len(hand.link_names)
    batch = points.shape[0]
    best_point = points.new_zeros(batch, link_count, 3)
    best_normal = points.new_zeros(batch, link_count, 3)
    best_depth = points.new_full((batch, link_count), -math.inf)
    rows = torch.arange(batch, device=points.device)
    for link in torch.unique(hand.surface_link).tolist():
        columns = (hand.surface_link == link).nonzero(as_tuple=True)[0]
        depth, deepest = distance[:, columns].max(dim=1)
        best_depth[:, link] = depth
        best_point[:, link] = points[rows, columns[deepest]]
        best_normal[:, link] = normal[rows, columns[deepest]]
    # A point deep inside, where the grid's gradient vanishes, has no normal and so no friction cone.
    return best_point, best_normal, (best_depth > -contact_distance_m) & (best_normal.norm(dim=-1) > 0.5)


def contact_wrenches(points: np.ndarray, outward_normals: np.ndarray, scale: float, friction: float, cone_edges: int) -> np.ndarray:
    """(C·E, 6) wrenches [f, p × f / scale] of the friction-cone edges of C contacts (unit normal component)."""
    inward = -outward_normals / np.linalg.norm(outward_normals, axis=1, keepdims=True)
    helper = np.where(np.abs(inward[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    tangent_a = np.cross(inward, helper)
    tangent_a /= np.linalg.norm(tangent_a, axis=1, keepdims=True)
    tangent_b = np.cross(inward, tangent_a)
    angle = 2.0 * np.pi * np.arange(cone_edges) / cone_edges
    forces = inward[:, None] + friction * (np.cos(angle)[None, :, None] * tangent_a[:, None] + np.sin(angle)[None, :, None] * tangent_b[:, None])
    torques = np.cross(np.broadcast_to(points[:, None], forces.shape), forces) / scale
    return np.concatenate([forces, torques], axis=-1).reshape(-1, 6)


def epsilon_quality(wrenches: np.ndarray) -> float:
    """Radius of the largest origin-centred ball inside the convex hull of ``wrenches`` (0 if the origin is not inside)."""
    if len(wrenches) <= wrenches.shape[1] or np.linalg.matrix_rank(wrenches, tol=RANK_TOLERANCE) < wrenches.shape[1]:
        return 0.0  # the wrenches span less than the full 6-D space: some wrench cannot be resisted
    try:
        hull = ConvexHull(wrenches)
    except QhullError:  # nearly flat hull: joggled input gives the same facets to ~1e-11
        hull = ConvexHull(wrenches, qhull_options="QJ")
    # Facets satisfy normal·w + offset <= 0 inside; the origin's distance to a facet is -offset.
    return float(max(0.0, -hull.equations[:, -1].max()))


@dataclass
class ForceClosureResult:
    """Per grasp: ε, NaN where it could not be computed, and why not ('' where it was)."""

    epsilon: np.ndarray  # (N,) float64
    failure_reason: np.ndarray  # (N,) str objects


def evaluate_force_closure(
    grasps: GraspSet,
    objects_dirs,
    model: ContactModel = ContactModel(),
    batch_size: int = 256,
    hand: ShadowHand | None = None,
    threads: int = 1,
) -> ForceClosureResult:
    """Per grasp, ε of its link contacts under ``model``.

    A grasp with a non-finite pose or scale, or whose object asset cannot be loaded, gets
    NaN and the reason; the other grasps are evaluated. Contacts come from torch in
    batches; the hulls (scipy's Qhull, ~90% of the time) are computed on ``threads``
    threads, as Qhull releases the GIL.
    """
    hand = hand if hand is not None else ShadowHand("cpu")
    epsilon = np.full(len(grasps), np.nan)
    failure_reason = invalid_grasp_reasons(grasps)
    object_ids = np.asarray([str(o) for o in grasps.object_id])
    with ThreadPoolExecutor(max_workers=max(1, int(threads))) as pool:
        for object_id in sorted(set(object_ids.tolist())):
            rows = np.nonzero((object_ids == object_id) & (failure_reason == ""))[0]
            if not len(rows):
                continue
            try:
                bank = SdfBank([load_asset(objects_dirs, object_id)], device=hand.device, dtype=hand.dtype)
            except ObjectAssetError as exc:
                log.warning("force closure: %s", exc)
                failure_reason[rows] = f"object asset unusable: {exc}"
                continue
            for start in range(0, len(rows), batch_size):
                idx = rows[start : start + batch_size]
                pose = torch.as_tensor(grasps.hand_pose[idx], dtype=hand.dtype, device=hand.device)
                scale = torch.as_tensor(grasps.scale[idx], dtype=hand.dtype, device=hand.device)
                points, normals, touching = link_contacts(hand, bank, pose, torch.zeros(len(idx), dtype=torch.long, device=hand.device), scale, model.contact_distance_m)
                points, normals, touching = points.double().cpu().numpy(), normals.double().cpu().numpy(), touching.cpu().numpy()
                wrench_sets = [
                    contact_wrenches(points[k, touching[k]], normals[k, touching[k]], float(grasps.scale[row]), model.friction, model.cone_edges)
                    for k, row in enumerate(idx)
                ]
                epsilon[idx] = list(pool.map(epsilon_quality, wrench_sets))
    return ForceClosureResult(epsilon, failure_reason)
