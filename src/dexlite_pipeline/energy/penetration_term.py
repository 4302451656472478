"""E_pen, the penetration of hand and object (``PenetrationTerm``): the largest of the grasp energy's terms, apart from
the small ones in ``energy.terms``, whose ``EnergyTerm``, ``EnergyContext`` and ``PenetrationResult`` it uses.
"""

from __future__ import annotations

import torch

from dexlite_pipeline.energy.link_map import LinkFrameMap
from dexlite_pipeline.energy.point_clusters import LEAVES_PER_PARENT, PADDING, build_point_clusters
from dexlite_pipeline.energy.spheres import build_hand_spheres
from dexlite_pipeline.energy.terms import EnergyContext, EnergyTerm, PenetrationResult
from dexlite_pipeline.hand.model import (
    BOX,
    CAPSULE,
    HandFrames,
    ShadowHand,
    box_signed_distance,
    capsule_signed_distance,
    shape_signed_distance,
)
from dexlite_pipeline.objects.assets import SdfBank
from dexlite_pipeline.objects.surface_distance import SurfaceDistance


class PenetrationTerm(EnergyTerm):
    """E_pen and the penetration depth: the hand and the object, each measured inside the other.

    The depth of a grasp (``PenetrationResult.depth_m``, the one measure every check uses) is
    the larger of two directions, each exact at its samples:

    - object in hand: object surface points inside the hand's capsules and boxes, by the
      shapes' analytic signed distances. Points are spread per area, ``point_spacing_m``
      apart on average at the grasp's own scale (not a fixed count per object, which is
      sparse on a large object): a grasp at scale s uses the first area·s²/spacing² points
      of the object's sequence (``surface_point_sequence``), so its result does not depend
      on the other grasps of its batch.
    - hand in object: r + d(c) over the hand's spheres (centre c, radius r; d positive
      inside). A capsule is its axis swept by a ball, so on a capsule this is the depth of
      the deepest object point in it, thin walls included, and it sees a link buried wholly
      inside, which the first direction cannot. With ``exact`` the distance of every sphere
      that may touch the object comes from the mesh (``SurfaceDistance``), not the grid.

    E_pen (metres) = Σ over object points of their depth inside the hand, each weighted by
    its share of the surface over ``REFERENCE_POINT_AREA_M2`` (so its scale does not depend
    on the sampling density; the reference is the area per point of DexGraspNet's 2,000
    points on a 10 cm object), plus Σ max(0, d(c)) over the sphere centres inside the
    object, zero until a link's axis is inside, about where the first part stops growing.
    ``GraspEnergy`` calls it once per evaluation to fill ``EnergyContext.penetration``;
    ``evaluate`` reads the energy from there.

    Exact culling keeps it cheap. Every sphere's depth is found first without autograd; a
    shape can hold object points only if one of its spheres reaches the object within the
    shape's covering gap plus the grid's interpolation error bound (see ``interpolation_error``),
    so all other shapes are skipped. Object points are tested in clusters (``point_clusters``):
    a cluster is opened only if its bounding sphere meets the shape's bounding sphere and
    the shape's own signed distance at the cluster centre is within the cluster radius
    (the distance is 1-Lipschitz). Which points lie inside which shapes is decided without
    autograd; only those (and the buried sphere centres) are evaluated again with
    gradients, straight from their link frames, so backward stays small.
    """

    # Float32 slack of the culling tests, so that rounding never drops a point (only adds candidates).
    CULL_SLACK_M = 1e-6
    CULL_SLACK_RELATIVE = 1e-4
    REFERENCE_POINT_AREA_M2 = 6.3e-5  # surface area one object point stands for in E_pen's scale, m² (2,000 points on a 10 cm sphere)

    name = "E_pen"
    weight_key = "pen"

    def __init__(
        self,
        hand: ShadowHand,
        sdf_bank: SdfBank,
        object_points: torch.Tensor,
        cluster_size: int = 8,
        object_area: torch.Tensor | None = None,
        point_spacing_m: float | None = None,
        surface: SurfaceDistance | None = None,
        leading_points: torch.Tensor | None = None,
    ) -> None:
        """``object_points`` (n_objects, P, 3), normalized frame, each object's sequence padded to P with
        far-away points; ``object_area`` (n_objects,) normalized surface areas and ``point_spacing_m``
        give each grasp its points (None: every point, each standing for ``REFERENCE_POINT_AREA_M2``);
        ``surface`` gives exact distances near the surface (None: the grid's). ``leading_points`` (n_objects,):
        how many points at the front of each object's set every grasp uses, before its area prefix
        (the judged measure's sharp-edge points); None: none."""
        self.hand = hand
        self.bank = sdf_bank
        self.surface = surface
        self.object_points = object_points  # (n_objects, P, 3), normalized frame
        self.object_area = object_area
        self.point_spacing_m = point_spacing_m
        self.leading_points = torch.zeros(object_points.shape[0], dtype=torch.long, device=object_points.device) if leading_points is None else leading_points.to(object_points.device)
        self.clusters = build_point_clusters(object_points, cluster_size, counts=(object_points < PADDING / 2).all(-1).sum(-1))
        # [m, |m|² − ρ², ρ, 1] per cluster and per parent (see ``_clusters_near``).
        self.cluster_aug = self._augmented(self.clusters.centre, self.clusters.radius)
        self.parent_aug = self._augmented(self.clusters.parent_centre, self.clusters.parent_radius)
        self.radius = hand.shape_bounding_radius
        self.interpolation_error = sdf_bank.voxel_size * 3**0.5 / 2  # normalized units, per object
        # Trilinear interpolation of an exact SDF f (1-Lipschitz) errs by at most
        # Σ wᵢ|cᵢ − x| ≤ (Σ wᵢ|cᵢ − x|²)^½ = h·(Σ_axes t(1−t))^½ ≤ h·√3/2 (t: fractional coordinate).
        self.spheres = build_hand_spheres(hand)
        link_count = len(hand.link_names)
        self.sphere_map = LinkFrameMap.for_points(self.spheres.centre_local, self.spheres.link, link_count)
        self.shape_map = LinkFrameMap.for_frames(hand.shape_rot, hand.shape_pos, hand.shape_link, link_count)
        self._kernel = None  # ``PenetrationKernel``, built on the first CPU evaluation

    def point_counts(self, object_index: torch.Tensor, scale: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Per grasp, how many of its object's points it uses (B,) and the E_pen weight of each (B,)."""
        total = self.object_points.shape[1]
        if self.object_area is None or self.point_spacing_m is None:
            return torch.full_like(object_index, total), torch.ones_like(scale)
        area_m2 = self.object_area.to(scale.dtype)[object_index] * scale.square()
        leading = self.leading_points[object_index]
        area_points = torch.ceil(area_m2 / self.point_spacing_m**2).long()
        count = (leading + area_points).clamp(1, total)
        return count, area_m2 / (count - leading).clamp(min=1) / self.REFERENCE_POINT_AREA_M2

    def evaluate(self, context: EnergyContext) -> torch.Tensor:
        return context.penetration.energy

    def __call__(self, frames: HandFrames, object_index: torch.Tensor, scale: torch.Tensor, exact: bool = False) -> PenetrationResult:
        """E_pen and the depths of a batch; ``exact``: sphere depths from the mesh (``SurfaceDistance``) near the surface.

        On the CPU the grid measure runs as one compiled pass (``energy.penetration_kernel``); elsewhere, and for
        ``exact``, as torch operations (``evaluate_with_torch``), which the kernel is tested against."""
        if not exact and self.object_points.device.type == "cpu":
            count, weight = self.point_counts(object_index, scale)
            return PenetrationResult(*self.kernel(frames, object_index, scale, count, weight))
        return self.evaluate_with_torch(frames, object_index, scale, exact)

    @property
    def kernel(self):
        """The compiled CPU pass (``penetration_kernel.PenetrationKernel``), built on first use (importing numba takes ~1 s)."""
        if self._kernel is None:
            from dexlite_pipeline.energy.penetration_kernel import PenetrationKernel

            self._kernel = PenetrationKernel(self)
        return self._kernel

    def evaluate_with_torch(self, frames: HandFrames, object_index: torch.Tensor, scale: torch.Tensor, exact: bool = False) -> PenetrationResult:
        """``__call__`` as torch operations, on any device."""
        batch = object_index.shape[0]
        radius = self.spheres.radius
        with torch.no_grad():
            centre = self.sphere_map(frames)  # (B, K, 3)
            distance, _ = self.bank.signed_distance(centre, object_index[:, None], scale[:, None], with_normal=False)
            sphere_depth = distance + radius
            shape_reach = sphere_depth.new_full((batch, len(self.radius)), -torch.inf)
            shape_reach = shape_reach.scatter_reduce(1, self.spheres.shape.expand(batch, -1), sphere_depth, "amax")
            margin = (self.interpolation_error[object_index] * scale)[:, None] + self.spheres.shape_gap[None, :]
            active = shape_reach > -margin
            b, k = (sphere_depth > radius).nonzero(as_tuple=True)  # centres inside the object
            if exact and self.surface is not None:
                sphere_depth = self.surface.signed_distance(centre, object_index[:, None], scale[:, None], band_m=radius) + radius
            hand_max = sphere_depth.max(dim=1).values.clamp(min=0)
        distance, _ = self.bank.signed_distance(self.sphere_map.rows(frames, b, k), object_index[b], scale[b], with_normal=False)
        hand_energy = distance.new_zeros(batch).index_add(0, b, distance)
        obj_energy, obj_max = self._object_in_hand(frames, active, object_index, scale)
        return PenetrationResult(obj_energy + hand_energy, obj_max, hand_max)

    def _object_in_hand(self, frames, active, object_index, scale):
        """Σ over the grasp's object points of their weighted depth inside the active shapes (deepest shape per point),
        and each grasp's deepest point (detached)."""
        batch = object_index.shape[0]
        _, weight = self.point_counts(object_index, scale)
        grasp, depth, share, deepest_max, _ = self._inside_points(frames, active, object_index, scale)
        return depth.new_zeros(batch).index_add(0, grasp, depth * share * weight[grasp]), deepest_max

    def _active_shapes(self, frames, object_index, scale) -> torch.Tensor:
        """(B, S) shapes one of whose spheres reaches the object within its covering gap and the grid's error (no autograd)."""
        with torch.no_grad():
            centre = self.sphere_map(frames)
            distance, _ = self.bank.signed_distance(centre, object_index[:, None], scale[:, None], with_normal=False)
            sphere_depth = distance + self.spheres.radius
            reach = sphere_depth.new_full((object_index.shape[0], len(self.radius)), -torch.inf)
            reach = reach.scatter_reduce(1, self.spheres.shape.expand(object_index.shape[0], -1), sphere_depth, "amax")
            margin = (self.interpolation_error[object_index] * scale)[:, None] + self.spheres.shape_gap[None, :]
            return reach > -margin

    def excess(
        self, frames: HandFrames, object_index: torch.Tensor, scale: torch.Tensor, allowed_m: float, shapes: torch.Tensor | None = None
    ) -> torch.Tensor:
        """(B,) Σ max(0, depth − ``allowed_m``)² over the hand's spheres and the grasp's object points, differentiable.

        The squared excess of the same two directions as the depth, with the spheres' distances from the
        mesh near the surface: zero exactly when the depth is within ``allowed_m``. ``shapes`` (S,) bool:
        only the excess of these hand shapes (their spheres, the object points deepest in them); None: all.
        """
        whole, only, _ = self.excess_and_depth(frames, object_index, scale, allowed_m, shapes)
        return whole if shapes is None else only

    def excess_and_depth(
        self, frames: HandFrames, object_index: torch.Tensor, scale: torch.Tensor, allowed_m: float, shapes: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor | None, torch.Tensor]:
        """From one pass over the hand's spheres and the object's points: the whole hand's ``excess`` (B,), that of
        ``shapes`` alone (B,; None without ``shapes``), both differentiable, and the judged depth (B,, m, detached: the
        ``exact`` measure of ``__call__``, the deeper of the deepest sphere and the deepest object point).
        Contact resolution (``optim.contact_resolution``) descends the excesses and stops a grasp by the depth.
        """
        radius = self.spheres.radius
        centre = self.sphere_map(frames)
        if self.surface is not None:
            distance = self.surface.signed_distance(centre, object_index[:, None], scale[:, None], band_m=radius)
        else:
            distance, _ = self.bank.signed_distance(centre, object_index[:, None], scale[:, None], with_normal=False)
        sphere_depth = distance + radius
        sphere_excess = torch.relu(sphere_depth - allowed_m).square()
        grasp, depth, _, deepest_point, shape = self._inside_points(frames, self._active_shapes(frames, object_index, scale), object_index, scale)
        point_excess = torch.relu(depth - allowed_m).square()
        whole = sphere_excess.sum(dim=1).index_add(0, grasp, point_excess)
        only = None
        if shapes is not None:
            mine_sphere, mine_point = shapes[self.spheres.shape].to(sphere_excess.dtype), shapes[shape].to(point_excess.dtype)
            only = (sphere_excess * mine_sphere).sum(dim=1).index_add(0, grasp, point_excess * mine_point)
        deepest_sphere = sphere_depth.detach().max(dim=1).values.clamp(min=0)
        return whole, only, torch.maximum(deepest_point, deepest_sphere)

    def _inside_points(self, frames, active, object_index, scale):
        """The grasp's own object points inside its active shapes, each once at its deepest shape:
        (grasp (N,), depth (N,) with gradients, share (N,) of exact ties, per-grasp deepest (B,) detached, shape (N,))."""
        batch = object_index.shape[0]
        count, _ = self.point_counts(object_index, scale)
        with torch.no_grad():
            pair_b, pair_s = active.nonzero(as_tuple=True)
            frame = self.shape_map(frames)[pair_b, pair_s]  # (A, 3, 4): [R | c]
            cand_pair, cand_point, depth = self._points_inside(frame, pair_b, pair_s, object_index, scale)
            grasp = pair_b[cand_pair]
            used = cand_point < count[grasp]  # the grasp's own points (its scale's prefix of the sequence)
            cand_pair, cand_point, depth, grasp = cand_pair[used], cand_point[used], depth[used], grasp[used]
            deepest_max = depth.new_zeros(batch).scatter_reduce(0, grasp, depth, "amax")
            # A point inside several shapes counts once, at its deepest; exact ties share it (as amax's gradient does).
            _, point_id = torch.unique(grasp * self.object_points.shape[1] + cand_point, return_inverse=True)
            deepest = depth.new_zeros(int(point_id.max()) + 1 if len(point_id) else 0).scatter_reduce(0, point_id, depth, "amax")
            winner = depth == deepest[point_id]
            cand_pair, cand_point, point_id, grasp = cand_pair[winner], cand_point[winner], point_id[winner], grasp[winner]
            share = 1.0 / torch.zeros_like(deepest).index_add(0, point_id, torch.ones_like(deepest[point_id]))[point_id]
        shape = pair_s[cand_pair]
        frame = self.shape_map.rows(frames, grasp, shape)
        local = self._apply(self._to_local(frame, scale[grasp]), self.object_points[object_index[grasp], cand_point])
        depth = shape_signed_distance(local, self.hand.shape_kind[shape], self.hand.shape_size[shape])
        return grasp, depth, share, deepest_max, shape

    @staticmethod
    def _to_local(frame: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
        """(N, 3, 4) affine maps from the normalized object frame to shape frames [R | c]: Rᵀ (s·p − c)."""
        rot_t = frame[:, :, :3].transpose(1, 2)
        return torch.cat([rot_t * scale[:, None, None], -(rot_t @ frame[:, :, 3:])], dim=2)

    @staticmethod
    def _apply(affine: torch.Tensor, points: torch.Tensor) -> torch.Tensor:
        """Affine maps (N, 3, 4) applied to points (N, 3), or to (N, L, 3) with one map per row of L points."""
        rows = points[:, None] if points.dim() == 2 else points
        out = torch.baddbmm(affine[:, None, :, 3], rows, affine[:, :, :3].transpose(1, 2))
        return out[:, 0] if points.dim() == 2 else out

    def _points_inside(self, frame, pair_b, pair_s, object_index, scale):
        """(pair, point index, depth) of every object point inside its pair's shape; no autograd.

        Per-row values are gathered with ``index_select`` from per-pair and per-cluster
        tables (much faster on CPU than advanced indexing of multi-dimensional tensors).
        """
        pair_object = object_index[pair_b]
        pair_scale = scale[pair_b]
        pair, cluster = self._clusters_near(frame[:, :, 3], pair_b, pair_s, pair_object, pair_scale)
        cluster = pair_object.index_select(0, pair) * self.clusters.radius.shape[1] + cluster  # flat cluster id
        to_local = self._to_local(frame, pair_scale).reshape(-1, 12)
        size = self.hand.shape_size.index_select(0, pair_s)
        row_kind = self.hand.shape_kind.index_select(0, pair_s).index_select(0, pair)
        centre = self.clusters.centre.reshape(-1, 3)
        radius = self.clusters.radius.reshape(-1)
        members = self.clusters.members.reshape(len(radius), -1)
        point_count = self.object_points.shape[1]
        flat_points = self.object_points.reshape(-1, 3)
        found = []
        for kind, distance in ((CAPSULE, self._capsule_distance), (BOX, box_signed_distance)):
            rows = (row_kind == kind).nonzero().squeeze(1)
            p, c = pair.index_select(0, rows), cluster.index_select(0, rows)
            affine = to_local.index_select(0, p).reshape(-1, 3, 4)
            shape_size = size.index_select(0, p)
            # The shape's signed distance at the cluster centre (1-Lipschitz) must come within the cluster radius.
            centre_depth = distance(self._apply(affine, centre.index_select(0, c)), shape_size)
            near = (centre_depth + radius.index_select(0, c) * pair_scale.index_select(0, p) > -self.CULL_SLACK_M).nonzero().squeeze(1)
            p, c, affine, shape_size = p.index_select(0, near), c.index_select(0, near), affine.index_select(0, near), shape_size.index_select(0, near)
            point = members.index_select(0, c)  # (M, L), −1 = padding
            flat = (pair_object.index_select(0, p)[:, None] * point_count + point.clamp(min=0)).reshape(-1)
            points = flat_points.index_select(0, flat).reshape(*point.shape, 3)
            depth = distance(self._apply(affine, points), shape_size[:, None])
            row, slot = ((depth > 0) & (point >= 0)).nonzero(as_tuple=True)
            found.append((p[row], point[row, slot], depth[row, slot]))
        return tuple(torch.cat(parts) for parts in zip(*found))

    @staticmethod
    def _capsule_distance(local, size):
        return capsule_signed_distance(local, size[..., 0], size[..., 1])

    @staticmethod
    def _augmented(centre: torch.Tensor, radius: torch.Tensor) -> torch.Tensor:
        """[m, |m|² − ρ², ρ, 1] per sphere (centre m, radius ρ), for ``_clusters_near``'s products."""
        rho = radius[..., None]
        return torch.cat([centre, centre.square().sum(-1, keepdim=True) - rho.square(), rho, torch.ones_like(rho)], dim=-1)

    def _clusters_near(self, centre, pair_b, pair_s, pair_object, pair_scale):
        """(pair, cluster) whose bounding spheres meet, |m − c|² − (R + ρ)² < 0: parents first, then their clusters.

        With m̃ = [m, |m|² − ρ², ρ, 1] per sphere and c̃ = [−2c, 1, −2R, |c|² − R²] per pair, m̃·c̃ is
        exactly that difference (normalized units; a slack relative to the largest terms covers float32
        cancellation). A cluster's sphere lies in its parent's, so a parent that misses the shape's sphere
        rules out its clusters: one product per object against the parents, then one row per
        (pair, parent) hit against that parent's ``LEAVES_PER_PARENT`` clusters.
        """
        centre_n = centre / pair_scale[:, None]
        reach_n = self.radius.index_select(0, pair_s) / pair_scale
        centre_sq = centre_n.square().sum(-1, keepdim=True)
        centre_aug = torch.cat([-2 * centre_n, torch.ones_like(centre_sq), -2 * reach_n[:, None], centre_sq - reach_n[:, None].square()], dim=1)
        slack_n = self.CULL_SLACK_RELATIVE * (1 + centre_sq + reach_n[:, None].square())
        pairs, clusters = [], []
        leaves = torch.arange(LEAVES_PER_PARENT, device=centre.device)
        for obj in torch.unique(pair_object).tolist():
            sel = (pair_object == obj).nonzero().squeeze(1)
            gap = centre_aug.index_select(0, sel) @ self.parent_aug[obj].T  # (a, parents)
            local_pair, parent = (gap < slack_n.index_select(0, sel)).nonzero(as_tuple=True)
            pair = sel.index_select(0, local_pair)
            cluster = (parent[:, None] * LEAVES_PER_PARENT + leaves).reshape(-1)  # (hits·16,)
            pair = pair.repeat_interleave(LEAVES_PER_PARENT)
            gap = (centre_aug.index_select(0, pair) * self.cluster_aug[obj].index_select(0, cluster)).sum(-1)
            near = (gap < slack_n.index_select(0, pair)[:, 0]).nonzero().squeeze(1)
            pairs.append(pair.index_select(0, near))
            clusters.append(cluster.index_select(0, near))
        empty = pair_b.new_zeros(0)
        return (torch.cat(pairs), torch.cat(clusters)) if pairs else (empty, empty)
