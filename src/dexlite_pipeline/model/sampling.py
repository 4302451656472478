"""Grasps from the trained CVAE: pure synthesis and dataset expansion.

- Pure synthesis (method ``cvae_raw``, held-out objects): PointNet on the object's cloud,
  an associated point drawn uniformly from the cloud (``association.random_points``),
  in the ``hand`` pose frame a uniformly random roll about its normal, z ~ N(0, I),
  decoder only.
- Dataset expansion (training objects), from a known grasp: its associated point from
  its ray; either the latent is perturbed, z = mu + sigma_expand * eps (method
  ``cvae_expand_latent``), or the associated point is moved to one of its nearest
  neighbours in the cloud and z = mu (method ``cvae_expand_point``); the ``hand`` pose
  frame keeps the known grasp's roll.

Each object (and scale) is one cloud: PointNet runs once per cloud, decoding is batched.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from dexlite_pipeline.model.association import nearest_to_ray, random_points
from dexlite_pipeline.model.data import ObjectClouds, cloud_keys
from dexlite_pipeline.model.network import GraspCVAE, anchor_at, condition_at
from dexlite_pipeline.model.pose import features_to_pose, pose_to_features

SYNTHESIS = "cvae_raw"
EXPAND_LATENT = "cvae_expand_latent"
EXPAND_POINT = "cvae_expand_point"


@dataclass(frozen=True)
class SampleConfig:
    """Config section ``sample``."""

    synthesis_grasps_per_object: int = 32  # held-out objects: pure synthesis
    expansion_grasps_per_object: int = 16  # training objects with lift-validated grasps
    scales: tuple[float, ...] = (0.08, 0.10, 0.12)  # synthesis scales, dealt in turn (those of the training grasps)
    expansion_latent_std: float = 0.5  # sigma of the latent perturbation
    expansion_point_fraction: float = 0.5  # share of expansions that move the associated point instead
    expansion_point_neighbours: int = 16  # the moved point is one of this many nearest cloud points
    points_per_cloud: int = 0  # 0 = the value the model was trained with

    def __post_init__(self) -> None:
        if not self.scales or min(self.scales) <= 0:
            raise ValueError("sample.scales must be a non-empty list of positive scales")


def _clouds_for(clouds: ObjectClouds, object_index: np.ndarray, scale: np.ndarray, points: int, generator: torch.Generator):
    """One drawn cloud per distinct (object, scale) and the cloud of each grasp."""
    keys = cloud_keys(np.asarray(object_index).astype(str), scale)
    first = np.array([np.flatnonzero(keys == k)[0] for k in range(keys.max() + 1)]) if len(keys) else np.zeros(0, int)
    drawn = clouds.draw(
        torch.as_tensor(object_index[first], device=clouds.device),
        torch.as_tensor(scale[first], dtype=torch.float32, device=clouds.device),
        points,
        generator,
    )
    return drawn, torch.as_tensor(keys, device=clouds.device)


@torch.no_grad()
def synthesize(
    model: GraspCVAE, clouds: ObjectClouds, object_index: np.ndarray, scale: np.ndarray, points: int, generator: torch.Generator
) -> torch.Tensor:
    """(B, 28) decoded poses for grasps on (object_index, scale) pairs, from the prior."""
    drawn, cloud_index = _clouds_for(clouds, object_index, scale, points, generator)
    point_index = random_points(len(object_index), points, generator).to(clouds.device)
    condition = model.condition(drawn, cloud_index, point_index)
    latent = torch.randn(len(object_index), model.config.latent_dim, generator=generator).to(clouds.device)
    anchor = model.sampling_anchors(anchor_at(drawn, cloud_index, point_index), generator)
    return features_to_pose(model.decode(latent, condition, anchor))


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
) -> torch.Tensor:
    """(B, 28) new poses near known grasps (B, 28): latent perturbed, or (``move_point``) associated point moved."""
    drawn, cloud_index = _clouds_for(clouds, object_index, scale, points, generator)
    point_index = nearest_to_ray(drawn[cloud_index], ray_origin, ray_direction)
    grasp_points = drawn[cloud_index, :, :3]
    neighbours = min(config.expansion_point_neighbours, points)
    ray_point = grasp_points[torch.arange(len(point_index)), point_index]
    nearest = (grasp_points - ray_point[:, None, :]).norm(dim=-1).topk(neighbours, largest=False).indices
    pick = torch.randint(neighbours, (len(point_index),), generator=generator).to(clouds.device)
    moved_index = nearest[torch.arange(len(point_index)), pick]
    features = model.pointnet(drawn)
    known = pose_to_features(known_pose)
    mu, _ = model.encode(known, condition_at(features, cloud_index, point_index), model.pose_anchors(anchor_at(drawn, cloud_index, point_index), known))
    noise = torch.randn(mu.shape, generator=generator).to(clouds.device) * config.expansion_latent_std
    latent = torch.where(move_point[:, None], mu, mu + noise)
    decode_index = torch.where(move_point, moved_index, point_index)
    condition = condition_at(features, cloud_index, decode_index)
    return features_to_pose(model.decode(latent, condition, model.pose_anchors(anchor_at(drawn, cloud_index, decode_index), known)))
