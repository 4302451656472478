"""A learned grasp evaluator: the probability that a simulated grasp holds its object.

The network sees the hand-object geometry, not raw pose numbers. The hand is a fixed set of
points spread over its collision shapes (``ShadowHand.surface_points`` with
``hand_points_per_shape`` per shape; for a hand from its MJCF, that many farthest-point samples of
each collision geom's surface samples, ``described_hand_points``), moved into the object frame by the
hand's forward kinematics. An evaluator is for one hand (config key ``hand``; its file records the
hand's record, a file without one is the Shadow Hand's), and ``load_evaluator(..., hand=record)``
refuses one of another hand in one line. Each hand point contributes its position, its height above the object surface
(along the outward normal of the nearest cloud point: negative inside), its distance to that
point, that normal and its height above the object's table (tabletop mode; a grasp without a table reads
as far above one). The object contributes a PointNet global feature of its cloud. An MLP
reads [global feature, all hand-point features in a fixed order] and returns two logits:
"held" (``lift_success``) and "six-direction success" (``six_dir_success``).

A *cloud* is one object at one scale: ``ObjectClouds.draw_fixed`` with ``points_per_cloud``
farthest-point samples in metres with normals. Farthest-point order means the first
``pointnet_points`` of a cloud are themselves an even subset, which PointNet reads; the hand
points are measured against the whole cloud.

Training splits validation by object, so the validation score estimates the score on objects
never seen, and the weights of the epoch with the lowest validation loss are kept.
"""

from __future__ import annotations

import copy
import json
import logging
import math
import os
import time
from dataclasses import asdict, dataclass, field, replace

import numpy as np
import torch
from torch import nn

from dexlite_pipeline.atomic import atomic_path
from dexlite_pipeline.hand.model import ShadowHand
from dexlite_pipeline.io.grasp_store import HAND, GraspSet, invalid_grasp_reasons, store_hand
from dexlite_pipeline.model.data import ObjectClouds, cloud_keys, farthest_point_indices
from dexlite_pipeline.model.hand_match import recorded_hand, same_hand, shadow_hand_record
from dexlite_pipeline.model.network import PointNet, _mlp
from dexlite_pipeline.model.pose import STORED_JOINTS_START, TRANSLATION_UNIT_M, turn_stored_poses, turned_clouds, vertical_rotation
from dexlite_pipeline.model.score_metrics import roc_auc
from dexlite_pipeline.objects.assets import ObjectAssetError, load_asset
from dexlite_pipeline.progress import ProgressLog

log = logging.getLogger(__name__)
FILE_FORMAT = "dexlite-grasp-evaluator"
FILE_VERSION = 2
HEADS = ("held", "six_dir")
NEVER_SIMULATED_PREFIXES = ("invalid_grasp", "not_tested")
HAND_POINT_FEATURES = 9  # per hand point: position (3), height above the surface, distance to it, nearest normal (3), height above the table
SUPPORT_COLUMNS = 4  # a grasp's table in its object frame: upward unit normal (3) and the origin's height above it (m); NaN = no table


class EvaluatorDataError(ValueError):
    """Grasp stores that give no usable training examples."""


@dataclass(frozen=True)
class EvaluatorConfig:
    """Sizes and training settings of the grasp evaluator (defaults: a few thousand grasps in ~1-2 min on 2 CPU cores)."""

    points_per_cloud: int = 512  # object surface points per cloud; hand points are measured against all of them
    pointnet_points: int = 128  # the first (farthest-point) points of each cloud that PointNet reads
    pointnet_widths: tuple[int, ...] = (32, 64, 128)  # PointNet layer widths; the last is the global feature size
    hand_points_per_shape: int = 6  # hand surface points per collision shape (6 -> 114 points)
    hidden_sizes: tuple[int, ...] = (128, 64)  # MLP hidden layers after [global feature, hand-point features]
    distance_scale_m: float = 0.02  # heights and distances enter as tanh(d / this), metres
    epochs: int = 30  # passes over the training grasps
    batch_size: int = 128  # grasps per step
    learning_rate: float = 1e-3  # AdamW step size
    weight_decay: float = 1e-4  # AdamW decoupled weight decay
    six_dir_loss_weight: float = 0.5  # weight of the six-direction loss beside the held loss (1)
    validation_fraction: float = 0.2  # share of the OBJECTS whose grasps form the validation set
    seed: int = 0  # initial weights, object split and batch order
    # Turn each training cloud, its grasps and their tables about the object's z axis (up on a table) by a random angle
    # every step: a grasp turned with its object is the same grasp, and a user's file sets that angle arbitrarily.
    rotation_augmentation: bool = True

    def __post_init__(self) -> None:
        if not 0 < self.pointnet_points <= self.points_per_cloud:
            raise ValueError(f"pointnet_points must be in 1..points_per_cloud ({self.points_per_cloud}), got {self.pointnet_points}")
        if self.epochs < 1 or self.batch_size < 1 or self.hand_points_per_shape < 1:
            raise ValueError("epochs, batch_size and hand_points_per_shape must be >= 1")
        if not 0.0 <= self.validation_fraction < 1.0:
            raise ValueError(f"validation_fraction must be in [0, 1), got {self.validation_fraction}")


def described_hand_points(hand, per_shape: int) -> tuple[torch.Tensor, torch.Tensor]:
    """A hand from its MJCF (``DescribedHand``): ``per_shape`` farthest-point samples of each collision geom's surface
    samples (all of them when it has fewer), in their link's frame (P, 3), and their links (P,)."""
    points, links = [], []
    for shape in hand.description.shapes:
        samples = torch.as_tensor(shape.points, dtype=hand.dtype)
        chosen = farthest_point_indices(samples, min(per_shape, len(samples)))
        points.append(samples[chosen])
        links += [hand.link_index[shape.link]] * len(chosen)
    return torch.cat(points).to(hand.device), torch.tensor(links, device=hand.device)


class GraspEvaluator(nn.Module):
    """PointNet of the object cloud + per-hand-point geometry -> logits (B, 2): [held, six-direction success].

    The hand (forward kinematics, not learned) is built on ``device``; the module must stay there. ``hand``: config key
    ``hand`` (shadow, allegro, leap or an MJCF path), ``hand_record`` what the evaluator's file records of it.
    """

    def __init__(self, config: EvaluatorConfig, device: torch.device | str = "cpu", hand: str = "shadow") -> None:
        super().__init__()
        self.config = config
        if str(hand) == shadow_hand_record()[HAND]:
            self.hand = ShadowHand(device, surface_points_per_shape=config.hand_points_per_shape)
            self.hand_record = shadow_hand_record()
            self._points_local, self._point_link = self.hand.surface_points_local, self.hand.surface_link
        else:
            from dexlite_pipeline.hand.choice import hand_record, resolve_hand

            self.hand = resolve_hand(hand, device)
            self.hand_record = hand_record(hand)
            self._points_local, self._point_link = described_hand_points(self.hand, config.hand_points_per_shape)
        self.pose_width = STORED_JOINTS_START + len(self.hand_record["joint_names"])
        self.hand_point_count = int(self._points_local.shape[0])
        self.pointnet = PointNet(config.pointnet_widths, normalization="none", normals=True)
        self.head = _mlp(config.pointnet_widths[-1] + HAND_POINT_FEATURES * self.hand_point_count, config.hidden_sizes, len(HEADS))
        self.to(device)

    def hand_points(self, hand_pose: torch.Tensor) -> torch.Tensor:
        """(B, K, 3) hand surface points in the object frame (metres) for poses (B, 6 + J)."""
        return self.hand.forward(hand_pose).transform(self._points_local, self._point_link)

    def hand_point_features(self, clouds: torch.Tensor, hand_points: torch.Tensor, support: torch.Tensor | None = None) -> torch.Tensor:
        """(B, K, 9) per hand point: position / 0.1 m, tanh(height above surface / s), tanh(distance / s), nearest normal,
        tanh(height above the table / s).

        ``clouds`` (B, P, 6) is each grasp's own cloud; s = ``distance_scale_m``; ``support`` (B, 4) each grasp's table
        (``SUPPORT_COLUMNS``; a row with NaN, or None for all, means no table: the height feature is 1, far above).
        """
        nearest = torch.cdist(hand_points.detach(), clouds[..., :3]).argmin(dim=2, keepdim=True).expand(-1, -1, 6)  # (B, K, 6)
        surface = clouds.gather(1, nearest)
        offset = hand_points - surface[..., :3]
        normal = surface[..., 3:6]
        scale = self.config.distance_scale_m
        height = torch.tanh((offset * normal).sum(-1, keepdim=True) / scale)
        distance = torch.tanh(offset.norm(dim=-1, keepdim=True) / scale)
        above_table = torch.ones_like(height)
        if support is not None:
            has_table = torch.isfinite(support).all(dim=1)
            plane = torch.nan_to_num(support)
            table_height = torch.tanh(((hand_points * plane[:, None, :3]).sum(-1, keepdim=True) + plane[:, None, 3:4]) / scale)
            above_table = torch.where(has_table[:, None, None], table_height, above_table)
        return torch.cat([hand_points / TRANSLATION_UNIT_M, height, distance, normal, above_table], dim=-1)

    def forward(
        self, clouds: torch.Tensor, hand_pose: torch.Tensor, cloud_index: torch.Tensor | None = None, support: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Logits (B, 2) for clouds (C, P, 6: metres at the grasp's scale in the object frame, outward normal) and poses (B, 6 + J).

        ``cloud_index`` (B,) names each grasp's cloud, so PointNet runs once per cloud; None: C == B, one cloud per grasp.
        ``support`` (B, 4): each grasp's table (``hand_point_features``); None: no table.
        """
        if clouds.shape[-1] != 6:
            raise ValueError(f"clouds must hold positions and normals, (C, P, 6), got {tuple(clouds.shape)}")
        if cloud_index is None:
            cloud_index = torch.arange(len(hand_pose), device=clouds.device)
        global_feature, _ = self.pointnet(clouds[:, : self.config.pointnet_points])
        features = self.hand_point_features(clouds[cloud_index], self.hand_points(hand_pose), support)
        return self.head(torch.cat([global_feature[cloud_index], features.flatten(1)], dim=1))


@dataclass
class EvaluatorExamples:
    """Simulated grasps with their labels and the clouds of their objects."""

    hand_pose: np.ndarray  # (N, 6 + J) float32
    object_id: np.ndarray  # (N,) str
    scale: np.ndarray  # (N,) float32, object scale (~radius, m)
    held: np.ndarray  # (N,) bool, lift_success
    six_dir: np.ndarray  # (N,) bool, six_dir_success (False where unknown)
    six_dir_known: np.ndarray  # (N,) bool, whether the store had six_dir_success
    support: np.ndarray  # (N, 4) float32, the grasp's table (SUPPORT_COLUMNS), NaN without one
    clouds: ObjectClouds
    object_index: np.ndarray  # (N,) int64 into ``clouds``
    excluded: dict[str, int] = field(default_factory=dict)  # reason -> grasps left out

    def __len__(self) -> int:
        return len(self.hand_pose)


def _exclusion_reasons(grasps: GraspSet, object_ids: set[str] | None) -> np.ndarray:
    """Per grasp '' if it is a usable example, else why not (never simulated first, then bad values, then the object filter)."""
    reasons = np.full(len(grasps), "", dtype=object)
    failure = grasps.arrays.get("failure_reason")
    if failure is not None:
        for prefix in NEVER_SIMULATED_PREFIXES:
            never = np.array([str(r).startswith(prefix) for r in failure], dtype=bool)
            reasons[never & (reasons == "")] = f"never simulated ({prefix})"
    bad = invalid_grasp_reasons(grasps)
    reasons[(reasons == "") & (bad != "")] = bad[(reasons == "") & (bad != "")]
    if object_ids is not None:
        outside = np.array([str(o) not in object_ids for o in grasps.object_id], dtype=bool)
        reasons[(reasons == "") & outside] = "object not in object_ids"
    return reasons


def _load_assets(objects_dirs: list[str], ids: list[str]) -> tuple[list, set[str]]:
    """Assets of ``ids`` (surface samples cut to the smallest count, so one ``ObjectClouds`` holds them) and the ids without one."""
    assets, missing = [], set()
    for object_id in ids:
        try:
            assets.append(load_asset(objects_dirs, object_id))
        except ObjectAssetError as exc:
            log.warning("evaluator examples: %s", exc)
            missing.add(object_id)
    if assets:
        fewest = min(len(a.surface_points) for a in assets)
        if any(len(a.surface_points) != fewest for a in assets):
            log.warning("objects hold different numbers of surface samples; every cloud is drawn from the first %d", fewest)
            assets = [replace(a, surface_points=a.surface_points[:fewest], surface_normals=a.surface_normals[:fewest]) for a in assets]
    return assets, missing


def support_of(grasps: GraspSet) -> np.ndarray:
    """(N, 4) each grasp's table from a store's ``support_normal`` / ``support_offset_m`` (tabletop mode); NaN without them."""
    normal, offset = grasps.arrays.get("support_normal"), grasps.arrays.get("support_offset_m")
    if normal is None or offset is None:
        return np.full((len(grasps), SUPPORT_COLUMNS), np.nan, np.float32)
    return np.concatenate([np.asarray(normal, np.float32).reshape(-1, 3), np.asarray(offset, np.float32).reshape(-1, 1)], axis=1)


def evaluator_examples(stores: list[GraspSet], objects_dirs: list[str], object_ids: set[str] | None = None) -> EvaluatorExamples:
    """Training examples from simulated grasp stores, restricted to ``object_ids`` when given.

    Left out, with counts per reason in ``excluded``: grasps never simulated (``failure_reason``
    starting with ``invalid_grasp`` or ``not_tested``), non-finite poses or scales, objects outside
    ``object_ids`` (held-out objects never enter), objects without a prepared asset.
    Raises ``EvaluatorDataError`` when a non-empty store has no ``lift_success`` or nothing is left.
    """
    kept: list[dict[str, np.ndarray]] = []
    reasons_all: list[np.ndarray] = []
    for grasps in stores:
        if len(grasps) == 0:
            continue
        if "lift_success" not in grasps.arrays:
            raise EvaluatorDataError("a grasp store has no lift_success array (not a simulated store)")
        reasons = _exclusion_reasons(grasps, object_ids)
        reasons_all.append(reasons)
        keep = reasons == ""
        six_dir = grasps.arrays.get("six_dir_success")
        kept.append({
            "hand_pose": np.asarray(grasps.hand_pose[keep], np.float32),
            "object_id": np.asarray([str(o) for o in grasps.object_id[keep]], dtype=object),
            "scale": np.asarray(grasps.scale[keep], np.float32),
            "held": np.asarray(grasps.arrays["lift_success"][keep], bool),
            "six_dir": np.zeros(int(keep.sum()), bool) if six_dir is None else np.asarray(six_dir[keep], bool),
            "six_dir_known": np.full(int(keep.sum()), six_dir is not None),
            "support": support_of(grasps)[keep],
        })
    arrays = {k: np.concatenate([part[k] for part in kept]) for k in kept[0]} if kept else {}
    reasons = np.concatenate(reasons_all) if reasons_all else np.zeros(0, dtype=object)
    excluded = {str(r): int((reasons == r).sum()) for r in sorted(set(reasons.tolist()) - {""})}
    ids = sorted(set(arrays["object_id"].tolist())) if arrays else []
    assets, missing = _load_assets(objects_dirs, ids)
    if missing:
        has_asset = np.array([o not in missing for o in arrays["object_id"]], dtype=bool)
        excluded["object has no prepared asset"] = int((~has_asset).sum())
        arrays = {k: v[has_asset] for k, v in arrays.items()}
    if not assets or len(arrays["hand_pose"]) == 0:
        raise EvaluatorDataError(f"no simulated grasps left for the evaluator (excluded: {excluded or 'none'})")
    clouds = ObjectClouds(assets)
    object_index = np.array([clouds.index_of[o] for o in arrays["object_id"]], dtype=np.int64)
    log.info("evaluator examples: %d kept; excluded %s", len(object_index), excluded or "none")
    return EvaluatorExamples(**arrays, clouds=clouds, object_index=object_index, excluded=excluded)


@dataclass
class TrainingHistory:
    """Per-epoch rows and the facts of one training run."""

    epochs: list[dict] = field(default_factory=list)  # epoch, step, seconds, train_loss, val_loss, val_auc_held, val_auc_six_dir
    train_object_ids: list[str] = field(default_factory=list)
    validation_object_ids: list[str] = field(default_factory=list)
    pos_weight: dict[str, float] = field(default_factory=dict)  # negatives / positives of the training split, per head
    best_epoch: int = 0  # the epoch whose weights were kept (lowest validation loss; the last without validation)


def split_objects(object_ids: np.ndarray, fraction: float, seed: int) -> tuple[list[str], list[str]]:
    """Seeded (train, validation) object ids; validation gets at least one object when ``fraction`` > 0 and there are two or more."""
    ordered = sorted(set(str(o) for o in object_ids))
    count = int(round(len(ordered) * fraction))
    if fraction > 0 and len(ordered) > 1:
        count = min(max(count, 1), len(ordered) - 1)
    order = np.random.default_rng([seed, 0xE7A1]).permutation(len(ordered))
    validation = sorted(ordered[i] for i in order[:count])
    return sorted(set(ordered) - set(validation)), validation


def _batch_inputs(clouds: ObjectClouds, object_index, scale, hand_pose, support, keys, index: np.ndarray, points: int, device):
    """(clouds (C, P, 6), poses (B, 6 + J), cloud_index (B,), support (B, 4)) for the grasps ``index``: one cloud per distinct
    (object, scale) key."""
    _, first, inverse = np.unique(keys[index], return_index=True, return_inverse=True)
    rows = index[first]
    drawn = clouds.draw_fixed(torch.as_tensor(object_index[rows]), torch.as_tensor(scale[rows], dtype=torch.float32), points)
    return (drawn.to(device), torch.as_tensor(hand_pose[index], device=device), torch.as_tensor(inverse.reshape(-1), device=device),
            torch.as_tensor(support[index], dtype=torch.float32, device=device))


def turned_inputs(inputs: tuple, angle_rad: torch.Tensor) -> tuple:
    """``_batch_inputs``' (clouds, poses, cloud_index, support) with cloud c and its grasps turned about the object's z axis
    by ``angle_rad[c]``: points and normals, palm pose, and the table's normal (its height is unchanged: the turn is
    about the origin, along the normal)."""
    clouds, hand_pose, cloud_index, support = inputs
    angle_rad = angle_rad.to(clouds.device, clouds.dtype)
    grasp_turn = vertical_rotation(angle_rad)[cloud_index]
    clouds = turned_clouds(clouds, angle_rad)
    support = torch.cat([(grasp_turn @ support[:, :3, None])[..., 0], support[:, 3:]], dim=1)
    return clouds, turn_stored_poses(hand_pose, angle_rad[cloud_index]), cloud_index, support


def _predict(model: GraspEvaluator, clouds: ObjectClouds, object_index, scale, hand_pose, support, batch_size: int) -> torch.Tensor:
    """Logits (N, 2) of grasps (N,) without gradients, in batches of ``batch_size``."""
    device, keys = next(model.parameters()).device, cloud_keys(object_index, scale)
    with torch.no_grad():
        parts = [
            model(*_batch_inputs(clouds, object_index, scale, hand_pose, support, keys, np.arange(start, min(start + batch_size, len(keys))),
                                 model.config.points_per_cloud, device)).cpu()
            for start in range(0, len(keys), batch_size)
        ]
    return torch.cat(parts) if parts else torch.zeros(0, len(HEADS))


def _pos_weight(labels: np.ndarray) -> float:
    positives = int(labels.sum())
    return float(np.clip((len(labels) - positives) / positives, 0.01, 100.0)) if positives else 1.0


def _loss(logits: torch.Tensor, labels: torch.Tensor, weight: torch.Tensor, pos_weight: torch.Tensor) -> torch.Tensor:
    """Mean over grasps of the weighted BCE summed over the heads (weight 0: label unknown)."""
    bce = nn.functional.binary_cross_entropy_with_logits(logits, labels, weight=weight, pos_weight=pos_weight, reduction="none")
    return bce.sum(1).mean()


def train_evaluator(
    examples: EvaluatorExamples, config: EvaluatorConfig = EvaluatorConfig(), device: torch.device | str = "cpu", hand: str = "shadow"
) -> tuple[GraspEvaluator, TrainingHistory]:
    """Train an evaluator on ``examples`` (grasps of hand ``hand``, config key ``hand``); deterministic for ``config.seed``
    and the torch thread count.

    Validation is a seeded share of the objects (scored as given, unturned). Each head's BCE weighs positives by the
    training split's negatives / positives, so a rare outcome is not ignored; the six-direction
    loss counts only grasps whose store had that label.
    """
    device = torch.device(device)
    train_ids, val_ids = split_objects(examples.object_id, config.validation_fraction, config.seed)
    in_train = np.isin(examples.object_id.astype(str), train_ids)
    train_index, val_index = np.flatnonzero(in_train), np.flatnonzero(~in_train)
    keys = cloud_keys(examples.object_id, examples.scale)
    labels = torch.as_tensor(np.stack([examples.held, examples.six_dir], axis=1), dtype=torch.float32)
    known = torch.as_tensor(np.stack([np.ones(len(examples), bool), examples.six_dir_known], axis=1), dtype=torch.float32)
    known[:, 1] *= config.six_dir_loss_weight
    history = TrainingHistory(train_object_ids=train_ids, validation_object_ids=val_ids)
    history.pos_weight = {
        "held": _pos_weight(examples.held[train_index]),
        "six_dir": _pos_weight(examples.six_dir[train_index][examples.six_dir_known[train_index]]),
    }
    pos_weight = torch.tensor([history.pos_weight[h] for h in HEADS], device=device)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(config.seed)
        model = GraspEvaluator(config, device, hand)
    optimizer = torch.optim.AdamW(model.parameters(), lr=config.learning_rate, weight_decay=config.weight_decay)
    rng = np.random.default_rng([config.seed, 0xBA7C4])
    steps_per_epoch = math.ceil(len(train_index) / config.batch_size)
    progress = ProgressLog(log, "evaluator training", steps_per_epoch * config.epochs, unit="steps")
    log.info("evaluator: %d training grasps on %d objects, %d validation grasps on %d objects, pos_weight %s",
             len(train_index), len(train_ids), len(val_index), len(val_ids), history.pos_weight)
    best_loss, best_state, step, started = math.inf, None, 0, time.perf_counter()
    for epoch in range(1, config.epochs + 1):
        model.train()
        order = rng.permutation(train_index)
        total = 0.0
        for start in range(0, len(order), config.batch_size):
            batch = order[start : start + config.batch_size]
            inputs = _batch_inputs(examples.clouds, examples.object_index, examples.scale, examples.hand_pose, examples.support, keys,
                                   batch, config.points_per_cloud, device)
            if config.rotation_augmentation:
                inputs = turned_inputs(inputs, torch.as_tensor(rng.uniform(0.0, 2 * math.pi, len(inputs[0]))))
            loss = _loss(model(*inputs), labels[batch].to(device), known[batch].to(device), pos_weight)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            total += float(loss.detach()) * len(batch)
            step += 1
            progress.advance()
        row = {"epoch": epoch, "step": step, "seconds": round(time.perf_counter() - started, 3), "train_loss": total / max(len(order), 1)}
        if len(val_index):
            model.eval()
            val_logits = _predict(model, examples.clouds, examples.object_index[val_index], examples.scale[val_index],
                                  examples.hand_pose[val_index], examples.support[val_index], 4 * config.batch_size)
            row["val_loss"] = float(_loss(val_logits, labels[val_index], known[val_index], pos_weight.cpu()))
            row["val_auc_held"] = roc_auc(val_logits[:, 0].numpy(), examples.held[val_index])
            six_known = examples.six_dir_known[val_index]
            row["val_auc_six_dir"] = roc_auc(val_logits[six_known, 1].numpy(), examples.six_dir[val_index][six_known])
            if row["val_loss"] < best_loss:
                best_loss, best_state, history.best_epoch = row["val_loss"], copy.deepcopy(model.state_dict()), epoch
        history.epochs.append(row)
        log.info("evaluator epoch %d: %s", epoch, ", ".join(f"{k} {v:.4g}" for k, v in row.items() if k != "epoch"))
    if best_state is not None:
        model.load_state_dict(best_state)
    else:
        history.best_epoch = config.epochs
    model.eval()
    return model, history


def score_grasps(
    model: GraspEvaluator, hand_pose: np.ndarray, clouds: ObjectClouds, object_id: np.ndarray, scale: np.ndarray,
    head: str = "held", batch_size: int = 512, support: np.ndarray | None = None,
) -> np.ndarray:
    """Probabilities (N,) from ``head`` ('held' or 'six_dir') for poses (N, 6 + J) of objects ``object_id`` (N,) in ``clouds`` at ``scale`` (N,);
    ``support`` (N, 4): each grasp's table (``SUPPORT_COLUMNS``), None: no table."""
    object_id = np.asarray([str(o) for o in object_id], dtype=object)
    unknown = sorted(set(object_id.tolist()) - set(clouds.object_ids))
    if unknown:
        raise ValueError(f"objects not in the clouds: {', '.join(unknown[:5])}")
    object_index = np.array([clouds.index_of[o] for o in object_id], dtype=np.int64)
    was_training = model.training
    model.eval()
    support = np.full((len(object_id), SUPPORT_COLUMNS), np.nan, np.float32) if support is None else np.asarray(support, np.float32)
    logits = _predict(model, clouds, object_index, np.asarray(scale, np.float32), np.asarray(hand_pose, np.float32).reshape(-1, model.pose_width), support,
                      batch_size)
    model.train(was_training)
    return torch.sigmoid(logits[:, HEADS.index(head)]).numpy()


def save_evaluator(path: str | os.PathLike, model: GraspEvaluator, config: EvaluatorConfig, meta: dict | None = None) -> None:
    """Write weights, config and ``meta`` (JSON-ready: objects, counts, history) to ``path`` atomically."""
    meta = dict(meta or {})
    try:
        json.dumps(meta)
    except TypeError as exc:
        raise ValueError(f"{path}: evaluator meta is not JSON-serializable: {exc}") from exc
    state = {k: v.detach().cpu() for k, v in model.state_dict().items()}
    payload = {"format": FILE_FORMAT, "version": FILE_VERSION, "config": asdict(config), "state_dict": state, "meta": meta,
               **json.loads(json.dumps(model.hand_record))}
    with atomic_path(path) as tmp:
        torch.save(payload, tmp)


def load_evaluator(path: str | os.PathLike, device: torch.device | str = "cpu", hand: dict | None = None) -> tuple[GraspEvaluator, dict]:
    """(model in eval mode on ``device``, meta) from a file written by ``save_evaluator``, with the hand it records (a
    file without one: the Shadow Hand). ``hand``: the run's hand record (``hand.choice.hand_record``); an evaluator of
    another hand raises ValueError in one line naming the file and both hands. None: any hand."""
    payload = torch.load(path, map_location="cpu", weights_only=True)
    if not isinstance(payload, dict) or payload.get("format") != FILE_FORMAT:
        raise ValueError(f"{path}: not a grasp evaluator file")
    if payload.get("version") != FILE_VERSION:
        raise ValueError(f"{path}: evaluator file version {payload.get('version')}, this code reads {FILE_VERSION}")
    recorded = recorded_hand(payload)
    if hand is not None and not same_hand(recorded, hand):
        raise ValueError(f"{path}: a grasp evaluator of hand {store_hand(recorded)}, this run's hand is {store_hand(hand)}: "
                         "train an evaluator for it")
    settings = dict(payload["config"])
    config = EvaluatorConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in settings.items()})
    model = GraspEvaluator(config, device, recorded[HAND])
    model.load_state_dict(payload["state_dict"])
    model.eval()
    return model, payload["meta"]
