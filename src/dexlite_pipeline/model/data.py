"""Training data for the CVAE: lift-validated grasps of training objects, their clouds and batches.

A *cloud* is one object at one scale (the object in metres is ``scale`` times its
normalized surface samples). A batch holds the grasps of a few clouds, so PointNet runs
once per cloud per step. A cloud is either a fixed farthest-point subset of the asset's
surface samples (``ObjectClouds.draw_fixed``, the default: each grasp keeps one
associated point) or a fresh random subset every step (``draw``); each grasp's
associated point is found in the cloud from the grasp's ray (``association``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import torch

from dexlite_pipeline.io.grasp_store import GraspSet, grasp_types, invalid_grasp_reasons
from dexlite_pipeline.model.association import grasp_rays
from dexlite_pipeline.model.hand_match import shadow_hand_record
from dexlite_pipeline.model.pose import STORED_JOINTS_START, pose_to_features
from dexlite_pipeline.model.table_frame import upright_rotations
from dexlite_pipeline.model.type_condition import GraspTypeRequestError, type_codes, vocabulary_of
from dexlite_pipeline.objects.assets import ObjectAsset
from dexlite_pipeline.tabletop import planes_from_store

log = logging.getLogger(__name__)


class TrainingDataError(ValueError):
    """Not enough usable grasps to train on."""


def select_training_grasps(lifted: GraspSet, train_object_ids: set[str], known_object_ids: set[str]) -> tuple[GraspSet, dict[str, int]]:
    """Lift-successful, valid grasps of training objects; also the count excluded per reason."""
    n = len(lifted)
    if n == 0:  # every lift shard empty (nothing curated): zero grasps, for the caller's min_grasps check
        return lifted, {}
    if "lift_success" not in lifted.arrays:
        raise TrainingDataError("the lift-validated grasps have no lift_success array")
    reasons = invalid_grasp_reasons(lifted, known_object_ids)
    is_train = np.array([oid in train_object_ids for oid in lifted.object_id], dtype=bool)
    reasons[(reasons == "") & ~is_train] = "object not in the training split"
    success = np.asarray(lifted.arrays["lift_success"], dtype=bool)
    reasons[(reasons == "") & ~success] = "failed the lift test"
    keep = reasons == ""
    excluded = {str(r): int((reasons == r).sum()) for r in sorted(set(reasons[~keep].tolist()))}
    log.info("training grasps: %d of %d kept; excluded %s", int(keep.sum()), n, excluded or "none")
    return lifted.select(keep), excluded


def split_validation(count: int, fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Seeded split of grasp indices into (train, validation); validation gets at least one grasp when count > 1."""
    order = np.random.default_rng(seed).permutation(count)
    n_val = int(round(count * fraction))
    if fraction > 0 and count > 1:
        n_val = min(max(n_val, 1), count - 1)
    return np.sort(order[n_val:]), np.sort(order[:n_val])


class ObjectClouds:
    """Normalized surface samples (with outward normals) of a set of objects, drawn into metre-scale clouds."""

    def __init__(self, assets: list[ObjectAsset], device: torch.device | str = "cpu", planes=None) -> None:
        """``planes`` (a ``tabletop.SupportPlanes``; None in floating mode): the tables the objects rest on, whose
        ``upright`` rotations turn a cloud into the generator's table frame (``model.table_frame``); the draws
        themselves stay in each object's own frame (the evaluator reads them so)."""
        self.device = torch.device(device)
        self.object_ids = [a.object_id for a in assets]
        self.upright = upright_rotations(self.object_ids, planes, self.device)  # (O, 3, 3) object frame -> table frame
        self.real_scales = [a.real_scale for a in assets]  # scale at the object's real size (metres files), else None
        self.index_of = {oid: i for i, oid in enumerate(self.object_ids)}
        sizes = {len(a.surface_points) for a in assets}
        if len(sizes) != 1:
            raise TrainingDataError(f"objects have different numbers of surface samples {sorted(sizes)}")
        self.surface = torch.as_tensor(np.stack([a.surface_points for a in assets]), dtype=torch.float32, device=self.device)
        self.normals = torch.as_tensor(np.stack([a.surface_normals for a in assets]), dtype=torch.float32, device=self.device)
        self._fixed: dict[int, torch.Tensor] = {}

    @property
    def samples_per_object(self) -> int:
        return int(self.surface.shape[1])

    def fixed_subset(self, points: int) -> torch.Tensor:
        """(objects, points) indices of a farthest-point subset of each object's samples, the same on every call.

        A fixed, evenly spread subset keeps each grasp's associated point and its normal
        in one place across steps (a fresh random draw of 512 of 4,096 samples moves the
        nearest point by ~1 cm), so the model sees one condition per grasp, and sampling
        reads the clouds the model was trained on.
        """
        total = self.samples_per_object
        if points > total:
            raise TrainingDataError(f"asked for {points} points per cloud, the assets hold {total}")
        cached = self._fixed.get(points)
        if cached is None:
            cached = torch.stack([farthest_point_indices(surface, points) for surface in self.surface])
            self._fixed[points] = cached
        return cached

    def draw_fixed(self, object_index: torch.Tensor, scale: torch.Tensor, points: int) -> torch.Tensor:
        """(C, points, 6) clouds like ``draw`` but of each object's ``fixed_subset``."""
        choice = self.fixed_subset(points)[object_index]
        rows = object_index[:, None]
        return torch.cat([self.surface[rows, choice] * scale[:, None, None], self.normals[rows, choice]], dim=2)

    def clouds(
        self, object_index: torch.Tensor, scale: torch.Tensor, points: int, fixed: bool, generator: torch.Generator | None
    ) -> torch.Tensor:
        """(C, points, 6) clouds: each object's ``fixed_subset`` when ``fixed``, else a ``draw`` with ``generator``."""
        if fixed:
            return self.draw_fixed(object_index, scale, points)
        return self.draw(object_index, scale, points, generator)

    def draw(self, object_index: torch.Tensor, scale: torch.Tensor, points: int, generator: torch.Generator | None) -> torch.Tensor:
        """(C, points, 6) clouds: [xyz in metres, outward unit normal] of a random subset (or the first ``points`` when no generator)."""
        total = self.samples_per_object
        if points > total:
            raise TrainingDataError(f"asked for {points} points per cloud, the assets hold {total}")
        if generator is None:
            choice = torch.arange(points, device=self.device).expand(len(object_index), points)
        else:
            choice = torch.rand(len(object_index), total, generator=generator).argsort(dim=1)[:, :points].to(self.device)
        rows = object_index[:, None]
        return torch.cat([self.surface[rows, choice] * scale[:, None, None], self.normals[rows, choice]], dim=2)


def farthest_point_indices(points: torch.Tensor, count: int) -> torch.Tensor:
    """(count,) indices of a farthest-point subset of ``points`` (P, 3), starting at point 0 (deterministic)."""
    chosen = torch.zeros(count, dtype=torch.long, device=points.device)
    distance = torch.full((len(points),), float("inf"), device=points.device)
    current = 0
    for i in range(count):
        chosen[i] = current
        distance = torch.minimum(distance, (points - points[current]).pow(2).sum(-1))
        current = int(distance.argmax())
    return chosen


@dataclass
class Batch:
    """Grasps (B,) of a few clouds (C,): ``cloud_index`` maps grasps to clouds."""

    grasp_index: np.ndarray
    cloud_object: torch.Tensor  # (C,) index into ObjectClouds
    cloud_scale: torch.Tensor  # (C,)
    cloud_index: torch.Tensor  # (B,)


def cloud_batches(
    cloud_key: np.ndarray, indices: np.ndarray, batch_size: int, clouds_per_batch: int, rng: np.random.Generator | None
) -> list[list[np.ndarray]]:
    """Split grasp ``indices`` into batches of at most ``clouds_per_batch`` chunks of one cloud each.

    Each grasp appears once. Grasps of one cloud are cut into chunks of
    ``batch_size // clouds_per_batch``; chunks are shuffled (when ``rng`` is given) and
    dealt into batches, each batch taking the next chunks whose clouds it does not hold
    yet, so a batch holds distinct clouds (BatchNorm then never normalizes a lone cloud)
    until only one cloud's chunks are left. PointNet runs once per chunk's cloud.
    """
    per_chunk = max(1, batch_size // max(1, clouds_per_batch))
    chunks: list[np.ndarray] = []
    for key in np.unique(cloud_key[indices]):
        members = indices[cloud_key[indices] == key]
        if rng is not None:
            members = rng.permutation(members)
        chunks += [members[i : i + per_chunk] for i in range(0, len(members), per_chunk)]
    order = rng.permutation(len(chunks)) if rng is not None else np.arange(len(chunks))
    remaining = [chunks[i] for i in order]
    batches = []
    while remaining:
        batch, clouds, left = [], set(), []
        for chunk in remaining:
            key = cloud_key[chunk[0]]
            if len(batch) < clouds_per_batch and key not in clouds:
                batch.append(chunk)
                clouds.add(key)
            else:
                left.append(chunk)
        batches.append(batch)
        remaining = left
    return batches


def make_batch(chunks: list[np.ndarray], cloud_key: np.ndarray, object_index: np.ndarray, scale: np.ndarray, device) -> Batch:
    """Assemble one batch, with one cloud per distinct (object, scale) among its chunks."""
    grasp_index = np.concatenate(chunks)
    keys, inverse = np.unique(cloud_key[grasp_index], return_inverse=True)
    first = np.array([grasp_index[np.flatnonzero(inverse == k)[0]] for k in range(len(keys))])
    return Batch(
        grasp_index=grasp_index,
        cloud_object=torch.as_tensor(object_index[first], device=device),
        cloud_scale=torch.as_tensor(scale[first], dtype=torch.float32, device=device),
        cloud_index=torch.as_tensor(inverse, device=device),
    )


def cloud_keys(object_id: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """One integer per distinct (object, scale) pair."""
    pairs = [f"{o}@{float(s):.6g}" for o, s in zip(object_id, scale)]
    return np.unique(pairs, return_inverse=True)[1]


def dataset_contacts(grasps: GraspSet) -> torch.Tensor:
    """(G, 4) contact indices of ``grasps`` (optimization from scratch stores them), rows of -1 where unknown."""
    contacts = grasps.arrays.get("contact_index")
    if contacts is None:
        return torch.full((len(grasps), 4), -1, dtype=torch.long)
    return torch.as_tensor(np.asarray(contacts, dtype=np.int64))


@dataclass
class TrainingData:
    """Everything the loop needs about the training grasps (already filtered)."""

    pose_features: torch.Tensor  # (G, 9 + J): the hand's J joints (31 for the Shadow Hand)
    ray_origin: torch.Tensor  # (G, 3)
    ray_direction: torch.Tensor  # (G, 3)
    contact_index: torch.Tensor  # (G, 4) the contacts each grasp was made with; -1 where the dataset has none
    object_index: np.ndarray  # (G,) into ``clouds`` and the energy's SDF bank (same object order)
    scale: np.ndarray  # (G,)
    cloud_key: np.ndarray  # (G,)
    clouds: ObjectClouds
    grasp_type: torch.Tensor  # (G,) each grasp's type as a column of ``type_vocabulary``
    type_vocabulary: tuple[str, ...]  # the types the model is conditioned on (``type_condition``)
    hand_record: dict  # the hand the poses are of ({"hand", "joint_names"[, "hand_sha256"]}: ``hand.choice.hand_record``)


def build_training_data(
    grasps: GraspSet, assets: list[ObjectAsset], hand, device: torch.device | str = "cpu", type_vocabulary: tuple[str, ...] | None = None,
    hand_record: dict | None = None,
) -> TrainingData:
    """Pose features, grasp rays, types and cloud bookkeeping of ``grasps`` on ``assets`` (their order is the bank order).

    ``hand`` is the hand model (``ShadowHand`` or ``DescribedHand``: the grasp rays) and ``hand_record`` what a model
    file records of it (None: the Shadow Hand's); the poses must be 6 + J wide for its J joints (``TrainingDataError``).
    ``type_vocabulary``: the types to condition on (a warm start keeps its model's); None: the grasps' own types
    (``grasp_store.grasp_types``: power for stores without them).
    """
    record = dict(hand_record) if hand_record is not None else shadow_hand_record()
    width = STORED_JOINTS_START + len(record["joint_names"])
    if grasps.hand_pose.ndim != 2 or grasps.hand_pose.shape[1] != width:
        raise TrainingDataError(f"training grasps: poses of {grasps.hand_pose.shape[-1]} numbers, hand {record['hand']} has {width}")
    types = grasp_types(grasps)
    vocabulary = vocabulary_of(types) if type_vocabulary is None else tuple(type_vocabulary)
    try:
        codes = type_codes(types, vocabulary)
    except GraspTypeRequestError as exc:
        raise TrainingDataError(f"training grasps: {exc}") from None
    clouds = ObjectClouds(assets, device, planes_from_store(grasps))
    pose = torch.as_tensor(grasps.hand_pose, dtype=torch.float32, device=device)
    with torch.no_grad():
        origin, direction = grasp_rays(hand, pose)
    scale = np.asarray(grasps.scale, dtype=np.float32)
    return TrainingData(
        pose_features=pose_to_features(pose),
        ray_origin=origin,
        ray_direction=direction,
        contact_index=dataset_contacts(grasps).to(device),
        object_index=np.array([clouds.index_of[str(o)] for o in grasps.object_id], dtype=np.int64),
        scale=scale,
        cloud_key=cloud_keys(grasps.object_id, scale),
        clouds=clouds,
        grasp_type=torch.as_tensor(codes, device=device),
        type_vocabulary=vocabulary,
        hand_record=record,
    )
