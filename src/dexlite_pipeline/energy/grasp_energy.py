"""All grasp energy terms of a batch of grasps at once, and their weighted sum.

``GraspEnergy`` holds the hand, the objects' SDF grids and surface points on one device
and evaluates every term for grasps given as stored 28-vectors or as (palm rotation
matrix, palm translation, joints), so 6D-rotation optimizers use it directly. The energy
is Σ w_k·E_k over a list of named terms (``energy.terms.EnergyTerm``) evaluated on one
shared ``EnergyContext``; weights live apart in ``EnergyWeights`` (config section
``energy.weights``), looked up by each term's ``weight_key``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
import torch

from dexlite_pipeline.energy.config import JUDGED_POINT_SPACING_M, EnergyConfig, EnergyWeights
from dexlite_pipeline.energy.contact_slots import CONTACT_COUNT, ContactSlots
from dexlite_pipeline.energy.link_map import LinkFrameMap
from dexlite_pipeline.energy.penetration_term import PenetrationTerm
from dexlite_pipeline.energy.point_clusters import PADDING
from dexlite_pipeline.energy.terms import (
    ContactDistanceTerm,
    EnergyContext,
    EnergyTerm,
    ForceClosureTerm,
    JointLimitTerm,
    SelfPenetrationTerm,
    TableTerm,
)
from dexlite_pipeline.hand.model import JOINTS, HandFrames, ShadowHand
from dexlite_pipeline.objects.assets import ObjectAsset, SdfBank
from dexlite_pipeline.objects.surface_distance import SurfaceDistance, sharp_edge_points, surface_point_sequence

# Largest grasp scale an object's E_pen points are drawn for when the caller names none (DexGraspNet's largest).
DEFAULT_MAX_SCALE = 0.15
# At most this many E_pen points per object (a 30 cm box at 2 mm spacing needs ~45,000); beyond it the spacing grows.
MAX_OBJECT_POINTS = 200_000
# Spacing of the judged measure's points along sharp edges, normalized units (0.4 mm at scale 0.1, 1.2 mm on a 30 cm box).
EDGE_POINT_SPACING = 0.004

# The terms of the grasp energy, in the order of ``EnergyResult.terms`` and of the weighted sum.
TERM_CLASSES: tuple[type[EnergyTerm], ...] = (ForceClosureTerm, ContactDistanceTerm, PenetrationTerm, SelfPenetrationTerm, JointLimitTerm)
TERM_NAMES = tuple(term.name for term in TERM_CLASSES)  # ("E_fc", "E_dis", "E_pen", "E_spen", "E_joints")
TERM_WEIGHT_KEYS: dict[str, str] = {term.name: term.weight_key for term in TERM_CLASSES}  # "E_fc" -> "fc", ...


def weighted_sum(weights, terms: Mapping[str, torch.Tensor], name_and_key: Iterable[tuple[str, str]]) -> torch.Tensor:
    """Σ weights.<key>·terms[name] over the (name, weight key) pairs, added left to right, (B,)."""
    total = None
    for name, key in name_and_key:
        part = getattr(weights, key) * terms[name]
        total = part if total is None else total + part
    if total is None:
        raise ValueError("weighted_sum needs at least one term")
    return total


def combined_energy(weights: EnergyWeights, terms: Mapping[str, torch.Tensor]) -> torch.Tensor:
    """Σ w_k E_k over the five terms (``TERM_NAMES``) with ``weights`` (``EnergyWeights``), (B,)."""
    return weighted_sum(weights, terms, TERM_WEIGHT_KEYS.items())


@dataclass
class EnergyResult:
    """Per-grasp terms (B,) in SI units, the weighted total, and detached diagnostics."""

    terms: dict[str, torch.Tensor]
    total: torch.Tensor
    contact_index: torch.Tensor  # (B, 4)
    penetration_mm: torch.Tensor  # deepest of: object point inside hand, hand point inside object
    contact_distance_mm: torch.Tensor  # mean |d| of the four contacts on the finger pads


class GraspEnergy:
    """Batched, differentiable E_fc, E_dis, E_pen, E_spen, E_joints for grasps on bank objects.

    ``terms`` lists the term objects summed into the total (one per ``TERM_CLASSES``); a new
    term is a new ``EnergyTerm`` subclass appended there, weighted by the ``EnergyWeights``
    field its ``weight_key`` names.
    """

    def __init__(
        self,
        hand: ShadowHand,
        sdf_bank: SdfBank,
        object_points: torch.Tensor,
        weights: EnergyWeights = EnergyWeights(),
        self_penetration_margin_m: float = 0.02,
        support_planes: torch.Tensor | None = None,
        object_area: torch.Tensor | None = None,
        point_spacing_m: float | None = None,
        surface: SurfaceDistance | None = None,
        judged_points: torch.Tensor | None = None,
        judged_leading: torch.Tensor | None = None,
    ) -> None:
        """``support_planes`` (n_objects, 4): per bank object the table's normal and offset per unit scale
        (tabletop mode; adds E_table). None: floating objects, the five terms only. ``object_points``,
        ``object_area``, ``point_spacing_m`` and ``surface``: see ``PenetrationTerm``. ``judged_points``: the
        objects' points for the judged depth (``judge``: their sharp edges' points, ``judged_leading`` per
        object, then points ``JUDGED_POINT_SPACING_M`` apart); None: E_pen's own."""
        self.hand = hand
        self.bank = sdf_bank
        self.weights = weights
        self.device = hand.device
        self.force_closure = ForceClosureTerm()
        self.contact_distance = ContactDistanceTerm()
        self.joint_limits = JointLimitTerm(hand.joint_limits)
        self.self_penetration = SelfPenetrationTerm(hand, self_penetration_margin_m)
        self.candidate_map = LinkFrameMap.for_points(hand.contact_points_local, hand.contact_link, len(hand.link_names))  # the pads
        pads = hand.pad_candidate_count  # the rest of the contact table: side and thumb-tip candidates (grasp types only)
        self.extra_candidate_map = LinkFrameMap.for_points(hand.all_contact_points_local[pads:], hand.all_contact_link[pads:], len(hand.link_names))
        self.contact_table_map = LinkFrameMap.for_points(hand.all_contact_points_local, hand.all_contact_link, len(hand.link_names))
        self._contact_kernel = None
        self.penetration = PenetrationTerm(
            hand,
            sdf_bank,
            object_points.to(self.device, hand.dtype),
            object_area=None if object_area is None else object_area.to(self.device, hand.dtype),
            point_spacing_m=point_spacing_m,
            surface=surface,
        )
        self._judge: PenetrationTerm | None = self.penetration if judged_points is None else None
        self._judged_points = judged_points
        self._judged_leading = judged_leading
        self.terms: list[EnergyTerm] = [self.force_closure, self.contact_distance, self.penetration, self.self_penetration, self.joint_limits]
        self.support_planes = None
        if support_planes is not None:
            self.support_planes = support_planes.to(self.device, hand.dtype)
            self.table = TableTerm(hand)
            self.terms.append(self.table)

    @classmethod
    def from_assets(
        cls, hand: ShadowHand, assets: list[ObjectAsset], config: EnergyConfig = EnergyConfig(), support_planes=None, max_scale=None
    ) -> "GraspEnergy":
        """Build the SDF bank, the exact surface distance and E_pen's per-area point sets.

        ``max_scale``: the largest scale the grasps of each object will have, a float for all or a
        mapping object id -> scale (missing ids: ``DEFAULT_MAX_SCALE``); each object gets the
        points ``config.object_point_spacing_m`` apart at that scale (a grasp at a larger scale
        gets fewer per area). ``support_planes`` (``tabletop.SupportPlanes``, tabletop mode):
        adds E_table with each asset's table.
        """
        bank = SdfBank(assets, device=hand.device, dtype=hand.dtype)
        meshes = [asset.load_mesh() for asset in assets]
        points, area, _ = object_point_sets(assets, meshes, config.object_point_spacing_m, max_scale)
        judged_points, _, judged_edges = object_point_sets(assets, meshes, JUDGED_POINT_SPACING_M, max_scale, with_edges=True)
        planes = None
        if support_planes is not None:
            rows = [(*support_planes.get(a.object_id).normal, support_planes.get(a.object_id).offset) for a in assets]
            planes = torch.tensor(rows, dtype=torch.float64)
        return cls(
            hand,
            bank,
            torch.as_tensor(points, dtype=hand.dtype),
            config.weights,
            config.self_penetration_margin_m,
            support_planes=planes,
            object_area=torch.as_tensor(area, dtype=hand.dtype),
            point_spacing_m=config.object_point_spacing_m,
            surface=SurfaceDistance.from_meshes(bank, meshes),
            judged_points=torch.as_tensor(judged_points, dtype=hand.dtype),
            judged_leading=torch.as_tensor(judged_edges),
        )

    @property
    def judge(self) -> PenetrationTerm:
        """The penetration measure that judges a grasp's start depth: E_pen's term on the objects' sharp
        edges and points ``JUDGED_POINT_SPACING_M`` apart (built on first use)."""
        if self._judge is None:
            self._judge = PenetrationTerm(
                self.hand,
                self.bank,
                self._judged_points.to(self.device, self.hand.dtype),
                object_area=self.penetration.object_area,
                point_spacing_m=JUDGED_POINT_SPACING_M,
                surface=self.penetration.surface,
                leading_points=self._judged_leading,
            )
        return self._judge

    def support(self, object_index: torch.Tensor, scale: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor] | tuple[None, None]:
        """Per grasp, the table's normal (B, 3) and offset in metres (B,); (None, None) for floating objects."""
        if self.support_planes is None:
            return None, None
        plane = self.support_planes[object_index]
        return plane[:, :3], plane[:, 3] * scale.to(plane.dtype)

    @property
    def object_ids(self) -> list[str]:
        return self.bank.object_ids

    def object_index(self, object_ids) -> torch.Tensor:
        """Bank indices (B,) of a sequence of object ids."""
        return self.bank.indices(object_ids)

    # ------------------------------------------------------------------ contacts
    @property
    def contact_kernel(self):
        """The chosen contacts' points, distances and normals compiled for the CPU (``energy.contact_kernel``), built on first use."""
        if self._contact_kernel is None:
            from dexlite_pipeline.energy.contact_kernel import ContactKernel  # imports numba: only when used

            self._contact_kernel = ContactKernel(self.bank, self.hand.all_contact_points_local, self.hand.all_contact_link)
        return self._contact_kernel

    def contact_points(self, frames: HandFrames, contact_index: torch.Tensor) -> torch.Tensor:
        """(B, 4, 3) object-frame positions of the chosen entries of the contact table (only those are computed)."""
        batch = torch.arange(contact_index.shape[0], device=contact_index.device)[:, None].expand_as(contact_index)
        return self.contact_table_map.rows(frames, batch.reshape(-1), contact_index.reshape(-1)).reshape(*contact_index.shape, 3)

    def nearest_contacts(
        self, frames: HandFrames, object_index: torch.Tensor, scale: torch.Tensor, slots: ContactSlots | None = None
    ) -> torch.Tensor:
        """(B, 4) indices of the four candidates closest to the object surface (smallest |d|).

        Used when a grasp comes without contact indices (imported or sampled grasps):
        the contacts a grasp actually makes are the pad points lying on the surface. With ``slots`` (a grasp type's
        contact template) contact k is its slot's candidate closest to the surface (slots of the same candidates, such
        as a pinch's two thumb-tip contacts, may then take the same one).
        """
        with torch.no_grad():
            candidates = self.candidate_map(frames)
            if slots is not None and slots.candidate_count > candidates.shape[1]:
                candidates = torch.cat([candidates, self.extra_candidate_map(frames)], dim=1)
            distance, _ = self.bank.signed_distance(candidates, object_index[:, None], scale[:, None])
            if slots is None:
                return distance.abs().topk(CONTACT_COUNT, dim=1, largest=False).indices
            allowed = slots.masks(distance.shape[1]).to(distance.device)  # (B, 4, N)
            return distance.abs()[:, None, :].expand_as(allowed).masked_fill(~allowed, float("inf")).argmin(dim=2)

    def best_contacts(
        self,
        hand_pose: torch.Tensor,
        object_index: torch.Tensor,
        scale: torch.Tensor,
        contact_index: torch.Tensor,
        samples: int,
        generator: torch.Generator,
        closeness_m: float = 0.002,
        draw=None,
        slots: ContactSlots | None = None,
    ) -> torch.Tensor:
        """(B, 4) contacts minimizing the contact-dependent energy, w_fc·E_fc + w_dis·E_dis, for fixed poses.

        Searches ``samples`` random 4-sets per grasp, drawn with probability ∝ exp(−|d|/closeness)
        so that pads near the surface are preferred, plus the current set (so it never gets
        worse). The pose-only terms do not depend on the contacts, so the total improves by
        exactly the same amount. ``draw(weight (B, N), count)`` -> (B, count) indices replaces the
        generator's draws (``optim.annealing.Draws``: each grasp's own stream). ``slots`` (a grasp type's
        contact template, ``ContactSlots``): contact k is drawn among its slot's candidates only (the weights
        normalized within the slot; ``draw`` then gets weights (B, 4, N) and returns (B, 4, count)); None: every
        contact among all 140 pads.
        """
        with torch.no_grad():
            frames = self.hand.forward(hand_pose)
            candidates = self.candidate_map(frames)
            if slots is not None and slots.candidate_count > candidates.shape[1]:
                candidates = torch.cat([candidates, self.extra_candidate_map(frames)], dim=1)
            distance, normal = self.bank.signed_distance(candidates, object_index[:, None], scale[:, None])
            batch, count = distance.shape
            if slots is None:
                weight = torch.softmax(-distance.abs() / closeness_m, dim=1).cpu()
                if draw is None:
                    draws = torch.multinomial(weight, samples * CONTACT_COUNT, replacement=True, generator=generator)
                else:
                    draws = draw(weight, samples * CONTACT_COUNT)
                draws = draws.reshape(batch, samples, CONTACT_COUNT)
            else:
                closeness = (-distance.abs() / closeness_m).cpu()[:, None, :].expand(batch, CONTACT_COUNT, count)
                weight = torch.softmax(closeness.masked_fill(~slots.masks(count), -torch.inf), dim=2)  # (B, 4, N)
                if draw is None:
                    per_slot = torch.multinomial(weight.reshape(batch * CONTACT_COUNT, count), samples, replacement=True, generator=generator)
                    per_slot = per_slot.reshape(batch, CONTACT_COUNT, samples)
                else:
                    per_slot = draw(weight, samples)
                draws = per_slot.transpose(1, 2)
            draws = torch.cat([contact_index.cpu()[:, None, :], draws], dim=1).to(self.device)
            flat = draws.reshape(batch, (samples + 1) * CONTACT_COUNT)
            points = torch.gather(candidates, 1, flat[..., None].expand(-1, -1, 3)).reshape(-1, CONTACT_COUNT, 3)
            normals = torch.gather(normal, 1, flat[..., None].expand(-1, -1, 3)).reshape(-1, CONTACT_COUNT, 3)
            dis = torch.gather(distance, 1, flat).abs().reshape(batch, samples + 1, CONTACT_COUNT).sum(-1)
            score = self.weights.fc * self.force_closure(points, normals).reshape(batch, samples + 1) + self.weights.dis * dis
            best = score.argmin(dim=1)
            return draws[torch.arange(batch, device=self.device), best]

    # -------------------------------------------------------------------- energy
    def context(
        self,
        hand_pose: torch.Tensor | None = None,
        *,
        object_index: torch.Tensor,
        scale: torch.Tensor,
        contact_index: torch.Tensor | None = None,
        palm_rot: torch.Tensor | None = None,
        palm_t: torch.Tensor | None = None,
        joints: torch.Tensor | None = None,
        exact_penetration: bool = False,
    ) -> EnergyContext:
        """The shared quantities the terms read, for the same arguments as ``__call__``.

        Computes the link frames, the contact points (chosen or, with ``contact_index`` None,
        the four candidates nearest the surface) with their signed distances and normals, and
        the penetration result, each once for all terms. ``exact_penetration``: also the judged
        depth (``judge``, against the mesh), in ``judged_depth_m``.
        """
        if hand_pose is not None:
            frames = self.hand.forward(hand_pose)
            joints = hand_pose[:, JOINTS.start :]  # the Shadow Hand's 22, or a hand from its MJCF's J
        else:
            if palm_rot is None or palm_t is None or joints is None:
                raise ValueError("GraspEnergy needs hand_pose or all of palm_rot, palm_t, joints")
            frames = self.hand.forward_parts(palm_rot, palm_t, joints)
        scale = scale.to(self.hand.dtype)
        if contact_index is None:
            contact_index = self.nearest_contacts(frames, object_index, scale)
        if self.device.type == "cpu":
            points, distance, normal = self.contact_kernel(frames, contact_index, object_index, scale)
        else:
            points = self.contact_points(frames, contact_index)
            distance, normal = self.bank.signed_distance(points, object_index[:, None], scale[:, None])
        support_normal, support_offset_m = self.support(object_index, scale)
        return EnergyContext(
            support_normal=support_normal,
            support_offset_m=support_offset_m,
            frames=frames,
            joints=joints,
            object_index=object_index,
            scale=scale,
            contact_index=contact_index,
            contact_points=points,
            contact_distance=distance,
            contact_normal=normal,
            penetration=self.penetration(frames, object_index, scale),
            judged_depth_m=self.judged_depth_m(frames, object_index, scale) if exact_penetration else None,
        )

    def judged_depth_m(self, frames: HandFrames, object_index: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
        """(B,) the judged penetration depth (m, detached): ``judge`` with sphere distances from the mesh."""
        with torch.no_grad():
            return self.judge(frames, object_index, scale.to(self.hand.dtype), exact=True).depth_m

    def __call__(
        self,
        hand_pose: torch.Tensor | None = None,
        *,
        object_index: torch.Tensor,
        scale: torch.Tensor,
        contact_index: torch.Tensor | None = None,
        palm_rot: torch.Tensor | None = None,
        palm_t: torch.Tensor | None = None,
        joints: torch.Tensor | None = None,
        exact_penetration: bool = False,
    ) -> EnergyResult:
        """Evaluate every term for a batch; pass ``hand_pose`` (B, 28) or ``palm_rot``/``palm_t``/``joints``.

        ``contact_index`` None chooses the four candidates nearest the surface. ``exact_penetration``:
        ``penetration_mm`` with sphere distances from the mesh near the surface (the judged depth;
        the terms are the same either way).
        """
        context = self.context(
            hand_pose,
            object_index=object_index,
            scale=scale,
            contact_index=contact_index,
            palm_rot=palm_rot,
            palm_t=palm_t,
            joints=joints,
            exact_penetration=exact_penetration,
        )
        terms = {term.name: term.evaluate(context) for term in self.terms}
        deepest = context.penetration.depth_m if context.judged_depth_m is None else context.judged_depth_m
        return EnergyResult(
            terms=terms,
            total=weighted_sum(self.weights, terms, ((term.name, term.weight_key) for term in self.terms)),
            contact_index=context.contact_index,
            penetration_mm=deepest * 1000.0,
            contact_distance_mm=context.contact_distance.detach().abs().mean(dim=1) * 1000.0,
        )


def max_scale_by_object(object_ids, scales) -> dict[str, float]:
    """Object id -> the largest of its grasps' scales (for ``GraspEnergy.from_assets``'s ``max_scale``)."""
    largest: dict[str, float] = {}
    for object_id, scale in zip(object_ids, np.asarray(scales, dtype=np.float64).reshape(-1)):
        if np.isfinite(scale):
            largest[str(object_id)] = max(largest.get(str(object_id), 0.0), float(scale))
    return largest


def energy_groups(count: int, objects_per_energy: int) -> list[slice]:
    """Consecutive groups of at most ``objects_per_energy`` of ``count`` objects (0: one group of all), each optimized with an
    energy of its own objects only, so memory is bounded by one group's (an object's energy: ~10-50 MB); none for no objects."""
    size = objects_per_energy or max(count, 1)
    return [slice(first, min(first + size, count)) for first in range(0, count, size)]


def object_point_sets(
    assets: list[ObjectAsset], meshes, spacing_m: float, max_scale=None, with_edges: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (n_objects, P, 3), normalized frame, padded with far points; each mesh's area and leading edge-point count (n_objects,).

    ``meshes``: the assets' normalized meshes (trimesh.Trimesh), in the same order. Each object
    gets the first area·s²/spacing² points of its ``surface_point_sequence`` for its largest scale
    s (``max_scale``: float, mapping object id -> scale, or None), at most ``MAX_OBJECT_POINTS``.
    ``with_edges``: first, points along its sharp edges (``sharp_edge_points``, ``EDGE_POINT_SPACING``
    apart in normalized units whatever the scale, so every grasp of the object uses all of them).
    """
    areas, sequences, leading = [], [], []
    for asset, mesh in zip(assets, meshes):
        if isinstance(max_scale, Mapping):
            scale = float(max_scale.get(asset.object_id, DEFAULT_MAX_SCALE))
        else:
            scale = float(DEFAULT_MAX_SCALE if max_scale is None else max_scale)
        area = float(mesh.area)
        count = int(min(MAX_OBJECT_POINTS, max(1, np.ceil(area * scale**2 / spacing_m**2))))
        edges = sharp_edge_points(mesh, EDGE_POINT_SPACING) if with_edges else np.zeros((0, 3), np.float32)
        areas.append(area)
        leading.append(len(edges))
        sequences.append(np.concatenate([edges, surface_point_sequence(mesh, count)]))
    width = max(len(p) for p in sequences)
    points = np.full((len(assets), width, 3), PADDING, dtype=np.float32)  # shorter sequences padded far from any hand
    for o, sequence in enumerate(sequences):
        points[o, : len(sequence)] = sequence
    return points, np.asarray(areas), np.asarray(leading)
