"""Grasps from the trained CVAE: pure synthesis and dataset expansion.

- Pure synthesis (method ``cvae_raw``, held-out objects): PointNet on the object's cloud,
  a latent from the configured prior (``latent_codes.sample_latents``: N(0, T²I), or training codes), an
  associated point by the configured rule (uniform, matched to the code's training grasp,
  debiased by how often nearby points were drawn, or farthest-point spread), in the ``hand``
  pose frame a uniformly random roll about its normal; decoder only.
- Dataset expansion (training objects), from a known grasp: its associated point from
  its ray; either the latent is perturbed, z = mu + sigma_expand * eps (method
  ``cvae_expand_latent``), or the associated point is moved to one of its nearest
  neighbours in the cloud and z = mu (method ``cvae_expand_point``); the ``hand`` pose
  frame keeps the known grasp's roll.

Each object (and scale) is one cloud: PointNet runs once per cloud, decoding is batched. A model conditioned on grasp
types (``type_condition``) decodes each grasp as the type asked of it (``sample.grasp_type``) from that type's codes;
an expansion or reconstruction keeps its known grasp's type.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from dexlite_pipeline.hand.model import POSE_DIM
from dexlite_pipeline.io.grasp_store import DEFAULT_GRASP_TYPE
from dexlite_pipeline.model.association import grasp_rays, nearest_to_ray, random_points
from dexlite_pipeline.model.config import ANCHOR_RULES, SampleConfig
from dexlite_pipeline.model.data import ObjectClouds, cloud_keys
from dexlite_pipeline.model.latent_codes import code_type_mask, feature_distances, sample_latents, training_cloud_features
from dexlite_pipeline.model.methods import PRIOR_ON_TRAINING, RECONSTRUCTION
from dexlite_pipeline.model.network import GraspCVAE, anchor_at, condition_at
from dexlite_pipeline.model.pose import box_centred_clouds, features_to_pose, pose_to_features, shift_translation, turned_clouds, vertical_rotation
from dexlite_pipeline.model.table_frame import rotate_clouds, rotate_grasps, rotate_vectors
from dexlite_pipeline.model.type_condition import requested_codes, type_codes


def _clouds_for(
    clouds: ObjectClouds, object_index: np.ndarray, scale: np.ndarray, points: int, generator: torch.Generator, fixed: bool = True
):
    """One cloud per distinct (object, scale) in the generator's table frame (``model.table_frame``), the cloud of each
    grasp, and each cloud's rotation from the object's frame into that frame (C, 3, 3): the fixed subset the model was
    trained on (``fixed``), else a random draw."""
    keys = cloud_keys(np.asarray(object_index).astype(str), scale)
    first = np.array([np.flatnonzero(keys == k)[0] for k in range(keys.max() + 1)]) if len(keys) else np.zeros(0, int)
    cloud_object = torch.as_tensor(object_index[first], device=clouds.device)
    cloud_scale = torch.as_tensor(scale[first], dtype=torch.float32, device=clouds.device)
    upright = clouds.upright[cloud_object]
    drawn = rotate_clouds(clouds.clouds(cloud_object, cloud_scale, points, fixed, generator), upright)
    return drawn, torch.as_tensor(keys, device=clouds.device), upright


def matched_yaws(model: GraspCVAE, drawn: torch.Tensor, candidates: int) -> torch.Tensor:
    """(C,) for each cloud the turn about z (radians), among ``candidates`` evenly spaced ones from 0, whose global
    feature (of the turned cloud with its bounding box centred again, ``box_centred_clouds``) lies nearest a training
    cloud's.

    The model's codes were encoded on its training objects as they stood, so a code carries a heading: a box turned
    90° from its family's training orientation is grasped across the wrong faces. Sampling on the turn of the new
    object that looks most like some training object, then turning the grasps back, gives every heading of the
    object the same grasps up to the spacing of the candidates (a round object, which looks alike at every turn,
    keeps the turn it came with).
    """
    cloud_feature, _ = training_cloud_features(model)
    cloud_feature = cloud_feature.to(drawn.device)
    angles = torch.arange(candidates, dtype=drawn.dtype, device=drawn.device) * (2 * math.pi / candidates)
    nearest = torch.stack([
        feature_distances(model.pointnet(box_centred_clouds(turned_clouds(drawn, angle.expand(len(drawn))))[0])[0], cloud_feature).min(dim=1).values
        for angle in angles
    ], dim=1)  # (C, candidates)
    # ties (a round object) keep the smallest turn, 0 first: argmin returns the first minimum
    return angles[nearest.argmin(dim=1)]


def debiased_points(
    points: torch.Tensor,
    cloud_index: torch.Tensor,
    generator: torch.Generator,
    region_m: float,
    prior_counts: torch.Tensor | None = None,
    candidates: torch.Tensor | None = None,
) -> torch.Tensor:
    """(B,) associated points drawn one grasp at a time, each point with weight 1 / (count + 1) (Dex1B's debiased rule).

    ``points`` (C, N, 3) are the clouds' positions (metres). A point's count is how many of the
    grasps already drawn on its cloud have their associated point within ``region_m`` of it,
    plus ``prior_counts`` (C, N) when given (e.g. how often training grasps used a similar
    point): regions already used become less likely, so a batch of grasps spreads over the
    surface instead of piling onto whichever patch the model favours. ``candidates`` (B, K)
    restricts each grasp's draw to those point indices (all points when None). Draws are in row order.
    """
    counts = prior_counts.clone().float() if prior_counts is not None else torch.zeros(points.shape[:2], device=points.device)
    chosen = torch.zeros(len(cloud_index), dtype=torch.long)
    for row, cloud in enumerate(cloud_index.tolist()):
        allowed = candidates[row] if candidates is not None else torch.arange(points.shape[1], device=points.device)
        weight = (counts[cloud, allowed] + 1.0).reciprocal()
        pick = int(allowed[int(torch.multinomial(weight.cpu(), 1, generator=generator))])
        chosen[row] = pick
        counts[cloud] += ((points[cloud] - points[cloud, pick]).norm(dim=-1) <= region_m).float()
    return chosen.to(points.device)


def spread_points(points: torch.Tensor, cloud_index: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """(B,) associated points spread over each cloud by farthest-point order: a cloud's first grasp takes a uniformly
    random point, each next one the point farthest from those its cloud's earlier grasps took (``points`` (C, N, 3))."""
    nearest = torch.full(points.shape[:2], float("inf"), device=points.device)  # distance to the nearest point taken
    used = torch.zeros(len(points), dtype=torch.bool)
    chosen = torch.zeros(len(cloud_index), dtype=torch.long)
    for row, cloud in enumerate(cloud_index.tolist()):
        pick = int(nearest[cloud].argmax()) if used[cloud] else int(torch.randint(points.shape[1], (1,), generator=generator))
        used[cloud] = True
        chosen[row] = pick
        nearest[cloud] = torch.minimum(nearest[cloud], (points[cloud] - points[cloud, pick]).norm(dim=-1))
    return chosen.to(points.device)


def matched_points(
    model: GraspCVAE, per_point: torch.Tensor, cloud_index: torch.Tensor, code_index: torch.Tensor, candidates: int = 1
) -> torch.Tensor:
    """(B, candidates) the points whose local feature is nearest that of the training grasp each latent came from, nearest first.

    ``per_point`` (C, N, F) are PointNet's per-point features of the clouds. A training
    grasp's code describes a hand relative to a patch of surface; decoding it where the new
    object has the most similar patch (by the network's own local feature) places it where
    a grasp of that kind fits, instead of at a uniformly random point.
    """
    wanted = model.codes_condition[code_index, model.config.pointnet_widths[-1] :].to(per_point.dtype)  # (B, F)
    keep = min(candidates, per_point.shape[1])
    chosen = torch.zeros(len(cloud_index), keep, dtype=torch.long, device=per_point.device)
    for cloud in torch.unique(cloud_index).tolist():  # one (rows, N) distance matrix per cloud, not a (B, N, F) difference
        rows = torch.nonzero(cloud_index == cloud)[:, 0]
        distance = torch.cdist(wanted[rows], per_point[cloud])  # (rows, N)
        chosen[rows] = distance.topk(keep, dim=1, largest=False).indices
    return chosen


def training_point_counts(model: GraspCVAE, per_point: torch.Tensor, chunk: int = 256) -> torch.Tensor:
    """(C, N) how many training grasps' associated points match each cloud point: each training grasp counts once,
    on the point whose local feature is nearest its own (``per_point`` (C, N, F) PointNet's per-point features)."""
    wanted = model.codes_condition[:, model.config.pointnet_widths[-1] :]  # (G, F)
    counts = torch.zeros(per_point.shape[:2], device=per_point.device)
    for cloud in range(len(per_point)):
        for start in range(0, len(wanted), chunk):
            distance = torch.cdist(wanted[start : start + chunk], per_point[cloud])  # (g, N)
            counts[cloud] += torch.bincount(distance.argmin(dim=1), minlength=per_point.shape[1]).float()
    return counts


@torch.no_grad()
def reconstruct(
    model: GraspCVAE,
    clouds: ObjectClouds,
    known_pose: torch.Tensor,
    ray_origin: torch.Tensor,
    ray_direction: torch.Tensor,
    object_index: np.ndarray,
    scale: np.ndarray,
    points: int,
    fixed_clouds: bool = True,
    generator: torch.Generator | None = None,
    grasp_type: np.ndarray | None = None,
) -> torch.Tensor:
    """(B, 6 + J) encoder-mean reconstructions of known grasps (B, 6 + J) of types ``grasp_type`` (B,; vocabulary columns):
    same cloud, same associated point, z = mu.

    The *fit* rung of the learning ladder: a model that learned its data returns each
    training grasp almost unchanged.
    """
    generator = generator if generator is not None else torch.Generator().manual_seed(0)
    drawn, cloud_index, to_table = _clouds_for(clouds, object_index, scale, points, generator, fixed_clouds)
    turn = to_table[cloud_index]
    point_index = nearest_to_ray(drawn[cloud_index], rotate_vectors(ray_origin, turn), rotate_vectors(ray_direction, turn))
    known = rotate_grasps(pose_to_features(known_pose), turn)
    condition = model.condition(drawn, cloud_index, point_index)
    anchor = model.pose_anchors(anchor_at(drawn, cloud_index, point_index), known)
    types = _type_tensor(grasp_type, known.device)
    mu, _ = model.encode(known, condition, anchor, types)
    return features_to_pose(rotate_grasps(model.generate(mu, condition, anchor, drawn, cloud_index, types), turn.transpose(1, 2)))


def _type_tensor(grasp_type: np.ndarray | None, device) -> torch.Tensor | None:
    """Vocabulary columns (B,) as a tensor on ``device`` (None stays None: a model that reads no type)."""
    return None if grasp_type is None else torch.as_tensor(np.asarray(grasp_type), dtype=torch.long, device=device)


@torch.no_grad()
def synthesize(
    model: GraspCVAE,
    clouds: ObjectClouds,
    object_index: np.ndarray,
    scale: np.ndarray,
    points: int,
    generator: torch.Generator,
    prior: str = "standard",
    temperature: float = 1.0,
    fixed_clouds: bool = True,
    anchor_rule: str = "uniform",
    neighbour_clouds: int = 1,
    anchor_region_m: float = 0.02,
    debias_training: bool = False,
    match_candidates: int = 1,
    debias_codes: bool = False,
    yaw_candidates: int = 1,
    grasp_type: np.ndarray | None = None,
) -> torch.Tensor:
    """(B, 6 + J) decoded poses (the model's hand's J joints) for grasps on (object_index, scale) pairs, from the latent ``prior`` (``sample_latents``).

    ``yaw_candidates`` > 1 (a model saved with its codes' conditions): each cloud is first turned about z to the one
    of that many evenly spaced headings that looks most like a training object (``matched_yaws``), moved in the table's
    plane to centre its bounding box (``box_centred_clouds``: where the object prepared at that heading would stand),
    sampled there, and the poses moved and turned back into the object's own frame.

    ``anchor_rule``: ``uniform`` (associated points uniformly random over the cloud),
    ``matched`` (``matched_points``; needs a prior drawn from the training codes, whose latents
    name their code; with ``match_candidates`` > 1 a debiased draw among that many best
    matches), ``debiased`` (``debiased_points`` with regions of ``anchor_region_m``; with
    ``debias_training`` the counts start from how many training grasps' local features match
    each point, ``training_point_counts``) or ``spread`` (``spread_points``). With
    ``debias_codes`` each cloud's training codes are drawn by ``debiased_codes``. ``grasp_type`` (B,) the type asked of
    each grasp (vocabulary columns; a model that reads types needs it): the decoder reads it, and latents come from the
    training codes of that type only (``code_type_mask``).
    """
    if anchor_rule not in ANCHOR_RULES:
        raise ValueError(f"anchor rule {anchor_rule!r} is not one of {', '.join(ANCHOR_RULES)}")
    if anchor_rule == "matched" and (prior == "standard" or len(model.codes_condition) == 0):
        raise ValueError("anchor rule 'matched' needs a latent prior drawn from the training codes and a model saved with their conditions")
    drawn, cloud_index, to_table = _clouds_for(clouds, object_index, scale, points, generator, fixed_clouds)
    offset = None  # the turned clouds' offsets in the table's plane (m), taken off so that each box is centred again
    if yaw_candidates > 1 and len(model.codes_condition) and len(model.codes_cloud) == len(model.codes_condition):
        yaw = matched_yaws(model, drawn, yaw_candidates)
        drawn, offset = box_centred_clouds(turned_clouds(drawn, yaw))
        to_table = vertical_rotation(yaw) @ to_table
    features = model.pointnet(drawn)
    latent, code_index = sample_latents(
        model, len(object_index), generator, prior, temperature, features[0][cloud_index], neighbour_clouds, cloud_index if debias_codes else None,
        code_type_mask(model, grasp_type),
    )
    if anchor_rule == "matched":
        matches = matched_points(model, features[1], cloud_index, code_index, match_candidates)
        if match_candidates <= 1:
            point_index = matches[:, 0]
        else:
            point_index = debiased_points(drawn[..., :3], cloud_index, generator, anchor_region_m, None, matches)
    elif anchor_rule == "debiased":
        prior_counts = training_point_counts(model, features[1]) if debias_training else None
        point_index = debiased_points(drawn[..., :3], cloud_index, generator, anchor_region_m, prior_counts)
    elif anchor_rule == "spread":
        point_index = spread_points(drawn[..., :3], cloud_index, generator)
    else:
        point_index = random_points(len(object_index), points, generator).to(clouds.device)
    condition = condition_at(features, cloud_index, point_index)
    anchor = model.sampling_anchors(anchor_at(drawn, cloud_index, point_index), generator)
    decoded = model.generate(latent, condition, anchor, drawn, cloud_index, _type_tensor(grasp_type, latent.device))
    if offset is not None:
        decoded = shift_translation(decoded, offset[cloud_index])
    # grasps of the cloud as the model read it (table frame, turned to the matched heading, box centred), back in the object's frame
    return features_to_pose(rotate_grasps(decoded, to_table[cloud_index].transpose(1, 2)))


@torch.no_grad()
def expand(
    model: GraspCVAE,
    clouds: ObjectClouds,
    known_pose: torch.Tensor,
    ray_origin: torch.Tensor,
    ray_direction: torch.Tensor,
    object_index: np.ndarray,
    scale: np.ndarray,
    move_point: torch.Tensor,
    config: SampleConfig,
    points: int,
    generator: torch.Generator,
    fixed_clouds: bool = True,
    grasp_type: np.ndarray | None = None,
) -> torch.Tensor:
    """(B, 6 + J) new poses near known grasps (B, 6 + J) of types ``grasp_type`` (B,; vocabulary columns), each of its known
    grasp's type: latent perturbed, or (``move_point``) associated point moved."""
    drawn, cloud_index, to_table = _clouds_for(clouds, object_index, scale, points, generator, fixed_clouds)
    turn = to_table[cloud_index]
    point_index = nearest_to_ray(drawn[cloud_index], rotate_vectors(ray_origin, turn), rotate_vectors(ray_direction, turn))
    grasp_points = drawn[cloud_index, :, :3]
    neighbours = min(config.expansion_point_neighbours, points)
    ray_point = grasp_points[torch.arange(len(point_index)), point_index]
    nearest = (grasp_points - ray_point[:, None, :]).norm(dim=-1).topk(neighbours, largest=False).indices
    pick = torch.randint(neighbours, (len(point_index),), generator=generator).to(clouds.device)
    moved_index = nearest[torch.arange(len(point_index)), pick]
    features = model.pointnet(drawn)
    known = rotate_grasps(pose_to_features(known_pose), turn)
    types = _type_tensor(grasp_type, known.device)
    mu, _ = model.encode(known, condition_at(features, cloud_index, point_index), model.pose_anchors(anchor_at(drawn, cloud_index, point_index), known),
                         types)
    noise = torch.randn(mu.shape, generator=generator).to(clouds.device) * config.expansion_latent_std
    latent = torch.where(move_point[:, None], mu, mu + noise)
    decode_index = torch.where(move_point, moved_index, point_index)
    condition = condition_at(features, cloud_index, decode_index)
    decoded = model.generate(latent, condition, model.pose_anchors(anchor_at(drawn, cloud_index, decode_index), known), drawn, cloud_index, types)
    return features_to_pose(rotate_grasps(decoded, turn.transpose(1, 2)))


@dataclass
class SampledRows:
    """Poses (B, 6 + J: the hand's J joints, 28 for the Shadow Hand) with their object ids, scales, method labels and grasp types."""

    hand_pose: torch.Tensor
    object_id: list[str]
    scale: np.ndarray
    method: list[str]
    reference_pose: np.ndarray | None = None  # (B, 6 + J) the known grasp a row reconstructs, NaN for other rows
    grasp_type: list[str] | None = None  # each row's grasp type; None: every row power (a model that knows only power)

    def references(self) -> np.ndarray:
        """``reference_pose``, or all NaN when the rows reconstruct no known grasp."""
        width = self.hand_pose.shape[1]
        return self.reference_pose if self.reference_pose is not None else np.full((len(self.method), width), np.nan, np.float32)

    def types(self) -> list[str]:
        """``grasp_type``, or power for every row."""
        return self.grasp_type if self.grasp_type is not None else [DEFAULT_GRASP_TYPE] * len(self.method)

    @classmethod
    def concatenate(cls, parts: list[SampledRows], device, pose_width: int = POSE_DIM) -> SampledRows:
        """The parts' rows in order (no parts: zero rows of ``pose_width`` numbers, 6 + J, on ``device``)."""
        return cls(
            hand_pose=torch.cat([p.hand_pose for p in parts]) if parts else torch.zeros(0, pose_width, device=device),
            object_id=[o for p in parts for o in p.object_id],
            scale=np.concatenate([p.scale for p in parts]) if parts else np.zeros(0, np.float32),
            method=[m for p in parts for m in p.method],
            reference_pose=np.concatenate([p.references() for p in parts]) if parts else np.zeros((0, pose_width), np.float32),
            grasp_type=[t for p in parts for t in p.types()],
        )


def synthesis_rows(
    model: GraspCVAE,
    clouds: ObjectClouds,
    object_ids: list[str],
    config: SampleConfig,
    points: int,
    generator: torch.Generator,
    fixed_clouds: bool,
    label: str,
    count: int | None = None,
) -> SampledRows:
    """``count`` (default ``synthesis_grasps_per_object``) pure syntheses per object (scales dealt in turn
    from ``config.scales``; with ``config.real_size`` an object known at real size is sampled at it), labelled ``label``,
    of the grasp types ``config.grasp_type`` asks for (``type_condition.requested_codes``: the same plan for every object;
    ``GraspTypeRequestError`` for a type the model does not know)."""
    count = config.synthesis_grasps_per_object if count is None else count
    plan = requested_codes(model.type_vocabulary, model.codes_type.cpu().numpy(), config.grasp_type, count, config.type_mix)
    obj = np.repeat([clouds.index_of[o] for o in object_ids], count)
    dealt = np.resize(np.asarray(config.scales, np.float32), count)
    real = getattr(clouds, "real_scales", None) or [None] * len(clouds.object_ids)
    scale = np.concatenate([
        np.full(count, real[clouds.index_of[o]], np.float32) if config.real_size and real[clouds.index_of[o]] else dealt for o in object_ids
    ]) if object_ids else np.zeros(0, np.float32)
    pose = synthesize(
        model, clouds, obj, scale, points, generator, config.latent_prior, config.latent_temperature, fixed_clouds, config.anchor_rule,
        config.neighbour_clouds, config.anchor_region_m, config.debias_training, config.match_candidates,
        config.debias_codes, config.yaw_candidates, np.tile(plan, len(object_ids)),
    )
    types = [model.grasp_types[t] for t in plan.tolist()] * len(object_ids)
    return SampledRows(hand_pose=pose, object_id=[clouds.object_ids[i] for i in obj], scale=scale, method=[label] * len(obj), grasp_type=types)


def ladder_rows(
    model: GraspCVAE,
    training_grasps: dict,
    clouds: ObjectClouds,
    object_ids: list[str],
    config: SampleConfig,
    points: int,
    generator: torch.Generator,
    hand,
    fixed_clouds: bool = True,
) -> SampledRows:
    """The learning ladder's grasps on training objects ``object_ids`` (those of this shard).

    - ``cvae_recon`` (fit): the encoder-mean reconstruction of every grasp the model was
      trained on (``training_grasps`` from the checkpoint), on its own cloud and associated point;
    - ``cvae_prior_train`` (in-distribution): ``synthesis_grasps_per_object`` pure syntheses
      per training object, by the same rule as on held-out objects (``synthesize``).

    ``config.ladder_grasps_per_object`` > 0 caps both per object: a seeded choice of that many of
    its training grasps, and that many prior samples (a large run's ladder then costs what its
    evaluation simulates, not a post-optimization of every training grasp).
    """
    wanted = set(object_ids)
    parts = []
    known_ids = np.asarray(training_grasps["object_id"], dtype=object)
    rows = np.flatnonzero([str(o) in wanted and str(o) in clouds.index_of for o in known_ids])
    cap = config.ladder_grasps_per_object
    if cap and len(rows):
        rows = np.sort(np.concatenate([
            np.asarray(group)[torch.randperm(len(group), generator=generator)[:cap].numpy()]
            for group in (rows[known_ids[rows] == oid] for oid in sorted(set(known_ids[rows].tolist())))
        ]))  # fmt: skip
    if len(rows):
        known = torch.as_tensor(training_grasps["hand_pose"], dtype=torch.float32)[rows].to(clouds.device)
        scale = np.asarray(training_grasps["scale"], dtype=np.float32)[rows]
        obj = np.array([clouds.index_of[str(o)] for o in known_ids[rows]])
        origin, direction = grasp_rays(hand, known)
        types = np.asarray(training_grasps.get("grasp_type") or [DEFAULT_GRASP_TYPE] * len(known_ids), dtype=object)[rows]
        pose = reconstruct(model, clouds, known, origin, direction, obj, scale, points, fixed_clouds, generator,
                           type_codes(types, model.type_vocabulary))
        parts.append(SampledRows(pose, [str(o) for o in known_ids[rows]], scale, [RECONSTRUCTION] * len(rows), known.cpu().numpy(),
                                 [str(t) for t in types]))
    present = [o for o in object_ids if o in clouds.index_of]
    prior_count = cap or config.synthesis_grasps_per_object
    if present and prior_count > 0:
        parts.append(synthesis_rows(model, clouds, present, config, points, generator, fixed_clouds, PRIOR_ON_TRAINING, prior_count))
    return SampledRows.concatenate(parts, clouds.device, model.pose_width)

