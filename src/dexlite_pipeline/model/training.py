"""Generator training (CVAE, or flow matching with ``train.generator: flow``): reconstruction + KL, optionally grasp
energies of the decoded pose.

Loss per batch = w_recon recon + w_KL KL + w_fc E_fc + w_dis E_dis + w_pen E_pen +
w_spen E_spen + w_joints E_joints (+ the terms read off the objects' surface samples, ``model.surface_terms``:
w_surface_pen surface_pen + w_surface_dis surface_dis), each term the mean over the batch's grasps (recon is
the squared error summed over the pose's components, ``pose.reconstruction_error``). The
energies, when weighted, are evaluated through differentiable forward kinematics of the
*decoded* pose (``energy_terms``); at weight 0 (the default) they are not computed, since
at the optimizer's weights they dominate the loss and the model stops fitting its data
(docs/learning.md). A flow model (``flow.GraspFlow``) replaces recon by its velocity's squared error, has no KL,
and its energies score the predicted clean pose. Weighted energies ramp from 0 to their values over the first
``energy_warmup_fraction`` of the steps; logged totals use the full weights.

Each cloud is a fixed farthest-point subset (``fixed_clouds``), batches hold
``clouds_per_batch`` clouds, Adam runs on a cosine schedule after a linear warm-up, and
gradients are clipped to ``grad_clip_norm``. After training, ``fit_training_codes``
stores each training grasp's code and condition in the model (what sampling draws from)
and returns the learning ladder's fit errors.

Deterministic for a seed: the weights are initialized from it, and batches, point
draws and latent noise come from seeded generators.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from dexlite_pipeline.energy.grasp_energy import GraspEnergy
from dexlite_pipeline.hand.rotation import matrix_to_euler_xyz
from dexlite_pipeline.model.data import Batch, TrainingData, cloud_batches, make_batch
from dexlite_pipeline.model.association import nearest_to_ray
from dexlite_pipeline.model.training_state import TrainingStateFile, restore, training_fingerprint
from dexlite_pipeline.model.config import ENERGY_TERMS, LOSS_TERMS, REFINE_TERM, SURFACE_TERMS, TABLE_TERM, TrainConfig
from dexlite_pipeline.model.flow import GraspFlow, generator_family, make_generator, network_config
from dexlite_pipeline.model.network import GraspCVAE, anchor_at, kl_divergence
from dexlite_pipeline.model.pose import features_to_parts, features_to_pose, pose_errors, reconstruction_error, shift_translation, vertical_rotation
from dexlite_pipeline.model.table_frame import rotate_clouds, rotate_grasps, rotate_vectors

log = logging.getLogger(__name__)

# (palm_rot (B,3,3), palm_t (B,3), joints (B,J), object_index (B,), scale (B,), dataset contacts (B,4), -1 = none)
#   -> {term: (B,)}
EnergyTerms = Callable[[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor], dict[str, torch.Tensor]]


def grasp_energy_terms(energy: GraspEnergy, contact_samples: int = 0, seed: int = 0) -> EnergyTerms:
    """The loss's energy terms from ``GraspEnergy`` at contacts chosen for each decoded pose.

    A grasp of the dataset that carries its contacts (``contact_index``: the four pads
    its optimization from scratch scored it at) is scored at those: the loss then asks the decoded pose
    to be that grasp, touching where it touched, and a faithful reconstruction scores
    what the grasp scored (E_fc < 0.3 for curated grasps).
    Otherwise (imported grasps; rows of -1) contacts are chosen without gradient and held
    fixed for the step: with ``contact_samples`` > 0, the best of that many random 4-sets
    of pads near the surface (``GraspEnergy.best_contacts``: lowest w_fc E_fc + w_dis
    E_dis); with 0, the four pads nearest the surface, which often lie on one finger, so
    E_fc stays high (about 10 on real DexGraspNet grasps, 0.75 with 64 samples).
    """
    generator = torch.Generator().manual_seed(seed)

    def terms(palm_rot, palm_t, joints, object_index, scale, dataset_contacts):
        known = (dataset_contacts >= 0).all(dim=1)
        contacts = dataset_contacts.clamp(min=0)
        if not bool(known.all()):
            with torch.no_grad():
                pose = torch.cat([palm_t, matrix_to_euler_xyz(palm_rot), joints], dim=1)
                chosen = energy.nearest_contacts(energy.hand.forward(pose), object_index, scale)
                if contact_samples > 0:
                    chosen = energy.best_contacts(pose, object_index, scale, chosen, contact_samples, generator)
            contacts = torch.where(known[:, None], contacts, chosen)
        result = energy(palm_rot=palm_rot, palm_t=palm_t, joints=joints, object_index=object_index, scale=scale, contact_index=contacts)
        names = ENERGY_TERMS if "E_table" not in result.terms else (*ENERGY_TERMS, TABLE_TERM)  # E_table: energy built with tables
        return {name: result.terms[f"E_{name}"] for name in names}

    return terms


def with_surface_terms(energy_terms: EnergyTerms, surface: Callable[..., dict[str, torch.Tensor]], mesh: bool) -> EnergyTerms:
    """``energy_terms`` (when ``mesh``: some mesh energy is weighted) and the surface-sample terms (``model.surface_terms``)
    of each decoded pose; ``batch_loss`` passes the training grasps' poses as ``target`` and their rows as ``grasp_index``."""

    def terms(palm_rot, palm_t, joints, object_index, scale, dataset_contacts, target, grasp_index=None):
        out = energy_terms(palm_rot, palm_t, joints, object_index, scale, dataset_contacts) if mesh else {}
        out.update(surface(palm_rot, palm_t, joints, object_index, scale, target, grasp_index=grasp_index))
        return out

    return terms


def vertical_turns(count: int, generator: torch.Generator, device: torch.device) -> torch.Tensor:
    """(count, 3, 3) rotations about the object frame's z axis (gravity's axis) by uniform random angles."""
    return vertical_rotation(torch.rand(count, generator=generator).to(device) * (2 * math.pi))


@dataclass
class TrainingResult:
    model: GraspCVAE
    history: list[dict]
    steps: int
    resumed_after_epoch: int = 0  # the saved epoch an interrupted run's state let this run start after (0: from the start)


def batch_loss(
    model: GraspCVAE,
    data: TrainingData,
    batch: Batch,
    points: int,
    energy_terms: EnergyTerms,
    weights: dict[str, float],
    generator: torch.Generator,
    energy_scale: float = 1.0,
    turn_clouds: bool = False,
    fixed_clouds: bool = False,
    refiner_start_noise_m: float = 0.0,
) -> tuple[torch.Tensor, dict[str, float]]:
    """Loss of one batch (energy weights times ``energy_scale``), and each term's batch mean with the full-weight total.

    Each cloud and its grasps are read in the object's table frame (``model.table_frame``: the table's normal along
    +z). With ``turn_clouds`` they are also turned about that vertical by a random angle (a grasp of a turned object
    is the turned grasp, and gravity keeps its direction), so the model learns grasps from the shape, not from the
    orientation of ten or so training objects. The decoded pose is turned back for the energies, which read the
    object's SDF in its own frame.
    """
    device = data.pose_features.device
    clouds = data.clouds.clouds(batch.cloud_object, batch.cloud_scale, points, fixed_clouds, generator)
    index = torch.as_tensor(batch.grasp_index, device=device)
    turn = data.clouds.upright[batch.cloud_object]
    if turn_clouds:
        turn = vertical_turns(len(clouds), generator, device) @ turn
    clouds = rotate_clouds(clouds, turn)
    grasp_turn = turn[batch.cloud_index]
    target = rotate_grasps(data.pose_features[index], grasp_turn)
    ray_origin = rotate_vectors(data.ray_origin[index], grasp_turn)
    ray_direction = rotate_vectors(data.ray_direction[index], grasp_turn)
    point_index = nearest_to_ray(clouds[batch.cloud_index], ray_origin, ray_direction)
    condition = model.condition(clouds, batch.cloud_index, point_index)
    anchor = model.pose_anchors(anchor_at(clouds, batch.cloud_index, point_index), target)
    if isinstance(model, GraspFlow):  # recon: the velocity's squared error; decoded: the predicted clean pose
        noise = torch.randn(len(index), model.pose_feature_dim, generator=generator).to(device)
        times = torch.rand(len(index), generator=generator).to(device)
        decoded, velocity_error = model.flow_loss(target, condition, anchor, noise, times, data.grasp_type[index])
        terms = {"recon": velocity_error, "kl": torch.zeros_like(velocity_error)}
    else:
        noise = torch.randn(len(index), model.config.latent_dim, generator=generator).to(device)
        decoded, mu, log_var = model(target, condition, anchor, noise, data.grasp_type[index])
        terms = {"recon": reconstruction_error(decoded, target), "kl": kl_divergence(mu, log_var)}
    has_refiner = model.refiner is not None
    if has_refiner:  # the refiner's pose is the model's output: its own squared error, and the energies read it
        if refiner_start_noise_m > 0:  # misses larger than the decoder's on its training grasps, to be corrected
            decoded = shift_translation(decoded, torch.randn(len(index), 3, generator=generator).to(device) * refiner_start_noise_m)
        decoded = model.refine(decoded, condition, anchor, clouds, batch.cloud_index, data.grasp_type[index])
        terms[REFINE_TERM] = reconstruction_error(decoded, target)
    loss_terms = tuple(weights)  # LOSS_TERMS (+ TABLE_TERM on a table)
    energy_names = tuple(name for name in loss_terms if name not in ("recon", "kl"))
    if any(weights[name] > 0 for name in energy_names):
        decoded = rotate_grasps(decoded, grasp_turn.transpose(1, 2))
        palm_rot, palm_t, joints = features_to_parts(decoded)
        object_index = torch.as_tensor(data.object_index[batch.grasp_index], device=device)
        scale = torch.as_tensor(data.scale[batch.grasp_index], dtype=torch.float32, device=device)
        surface = ({"target": features_to_parts(data.pose_features[index]), "grasp_index": index}
                   if any(n in SURFACE_TERMS for n in energy_names) else {})
        terms.update(energy_terms(palm_rot, palm_t, joints, object_index, scale, data.contact_index[index], **surface))
        for name in energy_names:  # the mesh energies, when only the surface-sample penetration is weighted
            if name not in terms:
                terms[name] = torch.full_like(terms["recon"], float("nan"))
    else:  # all energy weights 0: the terms are not computed (they cost most of a step), and log as NaN
        terms.update({name: torch.full_like(terms["recon"], float("nan")) for name in energy_names})
    means = {name: terms[name].mean() for name in loss_terms}
    weighted = {name: weights[name] * means[name] for name in loss_terms if weights[name] > 0 or name in ("recon", "kl")}
    if has_refiner:  # weighed as the decoder's recon
        means[REFINE_TERM] = terms[REFINE_TERM].mean()
        weighted[REFINE_TERM] = weights["recon"] * means[REFINE_TERM]
    total = sum(weighted.values())
    loss = sum(value * (energy_scale if name in energy_names else 1.0) for name, value in weighted.items())
    return loss, {"total": float(total.detach()), **{name: float(v.detach()) for name, v in means.items()}}


def learning_rate_factor(config: TrainConfig, step: int, planned_steps: int) -> float:
    """Multiplier of ``learning_rate`` at ``step``: linear warm-up over ``lr_warmup_steps``, then constant or cosine to 0."""
    if config.lr_warmup_steps > 0 and step < config.lr_warmup_steps:
        return (step + 1) / config.lr_warmup_steps
    if config.lr_schedule == "constant":
        return 1.0
    span = max(planned_steps - config.lr_warmup_steps, 1)
    progress = min(max(step - config.lr_warmup_steps, 0) / span, 1.0)
    return 0.5 * (1.0 + math.cos(math.pi * progress))


def _average(rows: list[tuple[int, dict[str, float]]]) -> dict[str, float]:
    count = sum(n for n, _ in rows)
    return {key: sum(n * r[key] for n, r in rows) / max(count, 1) for key in rows[0][1]} if rows else {}


def train_cvae(
    data: TrainingData,
    train_index: np.ndarray,
    val_index: np.ndarray,
    config: TrainConfig,
    energy_terms: EnergyTerms,
    seed: int,
    on_epoch: Callable[[dict], None] | None = None,
    table: bool = False,
    initial_model: GraspCVAE | None = None,
    state_file: TrainingStateFile | None = None,
) -> TrainingResult:
    """Train a fresh model, or go on training ``initial_model`` (a warm start: the data loop's rounds); returns it
    with one history row per epoch (train and validation means).

    ``state_file``: the training's state is saved there at epoch ends (``model.training_state``), and a state saved by
    an interrupted run of the same data, config, seed and warm start is loaded first: the run goes on from its last
    saved epoch to the model an uninterrupted run makes.

    ``table`` (tabletop mode; ``energy_terms`` built on an energy with tables): E_table is a loss term too.
    The optimizer and learning-rate schedule start afresh either way.
    """
    device = data.pose_features.device
    torch.manual_seed(seed)
    fresh = make_generator(config, data.type_vocabulary, data.hand_record) if initial_model is None else None
    if initial_model is not None and generator_family(initial_model) != config.generator:
        raise ValueError(f"warm start: the model is a {generator_family(initial_model)}, train.generator is {config.generator}")
    if initial_model is not None and initial_model.hand_record["joint_names"] != list(data.hand_record["joint_names"]):
        raise ValueError(f"warm start: the model is of hand {initial_model.hand_record['hand']}, the grasps of hand {data.hand_record['hand']}")
    if initial_model is not None and initial_model.config != network_config(config, initial_model.joint_count):
        raise ValueError(f"warm start: the model's network config {initial_model.config} differs from train.model {config.model}")
    if initial_model is not None and initial_model.type_vocabulary != data.type_vocabulary:
        raise ValueError(f"warm start: the model's grasp types {initial_model.type_vocabulary} differ from the data's {data.type_vocabulary}")
    model = fresh.to(device) if initial_model is None else initial_model.to(device)
    optimizer = torch.optim.Adam(model.parameters(), lr=config.learning_rate)
    weights = config.weights(table)
    batch_rng = np.random.default_rng(seed)
    generator = torch.Generator().manual_seed(seed + 1)
    val_generator_seed = seed + 2
    steps_per_epoch = len(cloud_batches(data.cloud_key, train_index, config.batch_size, config.clouds_per_batch, None))
    epochs = config.epochs
    if config.max_steps > 0:
        epochs = max(1, min(epochs, math.ceil(config.max_steps / max(steps_per_epoch, 1))))
    planned_steps = epochs * steps_per_epoch if config.max_steps <= 0 else min(epochs * steps_per_epoch, config.max_steps)
    warmup_steps = int(config.energy_warmup_fraction * planned_steps)
    scheduler = torch.optim.lr_scheduler.LambdaLR(optimizer, lambda k: learning_rate_factor(config, k, planned_steps))
    log.info(
        "training on %d grasps (%d validation), %d steps per epoch, %d epochs, energy warm-up %d steps, profile %s",
        len(train_index), len(val_index), steps_per_epoch, epochs, warmup_steps, config.profile,
    )
    history: list[dict] = []
    step, first_epoch, seconds_before = 0, 1, 0.0
    fingerprint = training_fingerprint(config, seed, data, train_index, val_index, initial_model, state_file.context) if state_file is not None else ""
    saved = state_file.load(fingerprint) if state_file is not None else None
    if saved is not None:
        restore(saved, model=model, optimizer=optimizer, scheduler=scheduler, batch_rng=batch_rng, generator=generator)
        history, step, first_epoch, seconds_before = saved["history"], saved["step"], saved["epoch"] + 1, saved["seconds"]
        log.info("going on from the training state of %s: epoch %d, step %d of %d", state_file.path, saved["epoch"], step, planned_steps)
    start = time.perf_counter() - seconds_before
    for epoch in range(first_epoch, epochs + 1):
        if step >= planned_steps:
            break
        model.train()
        rows = []
        for chunks in cloud_batches(data.cloud_key, train_index, config.batch_size, config.clouds_per_batch, batch_rng):
            if step >= planned_steps:
                break
            batch = make_batch(chunks, data.cloud_key, data.object_index, data.scale, device)
            energy_scale = min(1.0, step / warmup_steps) if warmup_steps else 1.0
            loss, terms = batch_loss(
                model, data, batch, config.points_per_cloud, energy_terms, weights, generator, energy_scale,
                config.rotation_augmentation, config.fixed_clouds, config.refiner_start_noise_m,
            )
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            if config.grad_clip_norm > 0:
                torch.nn.utils.clip_grad_norm_(model.parameters(), config.grad_clip_norm)
            optimizer.step()
            scheduler.step()
            rows.append((len(batch.grasp_index), terms))
            step += 1
        row = {"epoch": epoch, "step": step, "seconds": round(time.perf_counter() - start, 3)}
        row.update({f"train_{k}": v for k, v in _average(rows).items()})
        if len(val_index):
            row.update({f"val_{k}": v for k, v in evaluate_loss(model, data, val_index, config, energy_terms, val_generator_seed, table).items()})
        history.append(row)
        if state_file is not None and state_file.due() and step < planned_steps and epoch < epochs:
            state_file.save(fingerprint, epoch=epoch, step=step, seconds=row["seconds"], history=history, model=model,
                            optimizer=optimizer, scheduler=scheduler, batch_rng=batch_rng, generator=generator)
        if on_epoch is not None:
            on_epoch(row)
    return TrainingResult(model=model, history=history, steps=step, resumed_after_epoch=first_epoch - 1)


@torch.no_grad()
def evaluate_loss(
    model: GraspCVAE, data: TrainingData, index: np.ndarray, config: TrainConfig, energy_terms: EnergyTerms, seed: int, table: bool = False
) -> dict[str, float]:
    """Mean loss terms over ``index`` in eval mode, with the same point draws and noise every time."""
    model.eval()
    generator = torch.Generator().manual_seed(seed)
    rows = []
    for chunks in cloud_batches(data.cloud_key, index, config.batch_size, config.clouds_per_batch, None):
        batch = make_batch(chunks, data.cloud_key, data.object_index, data.scale, data.pose_features.device)
        _, terms = batch_loss(
            model, data, batch, config.points_per_cloud, energy_terms, config.weights(table), generator, fixed_clouds=config.fixed_clouds
        )
        rows.append((len(batch.grasp_index), terms))
    return _average(rows)


@torch.no_grad()
def encode_training_grasps(
    model: GraspCVAE, data: TrainingData, index: np.ndarray, config: TrainConfig
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Posterior (mu, log sigma^2), the encoder-mean reconstruction (features, object frame) and the condition
    (global and local feature) of grasps ``index``.

    Eval mode, each grasp on the cloud it was trained on (the fixed subset, or the first
    ``points_per_cloud`` samples when clouds were drawn at random) and at its associated point.
    """
    model.eval()
    mus, log_vars, decoded, grasp_ids, local = [], [], [], [], []
    for chunks in cloud_batches(data.cloud_key, np.asarray(index), config.batch_size, config.clouds_per_batch, None):
        batch = make_batch(chunks, data.cloud_key, data.object_index, data.scale, data.pose_features.device)
        turn = data.clouds.upright[batch.cloud_object]  # the table frame the model reads (``model.table_frame``)
        clouds = rotate_clouds(data.clouds.clouds(batch.cloud_object, batch.cloud_scale, config.points_per_cloud, config.fixed_clouds, None), turn)
        rows = torch.as_tensor(batch.grasp_index, device=clouds.device)
        grasp_turn = turn[batch.cloud_index]
        target = rotate_grasps(data.pose_features[rows], grasp_turn)
        point_index = nearest_to_ray(clouds[batch.cloud_index], rotate_vectors(data.ray_origin[rows], grasp_turn),
                                     rotate_vectors(data.ray_direction[rows], grasp_turn))
        condition = model.condition(clouds, batch.cloud_index, point_index)
        anchor = model.pose_anchors(anchor_at(clouds, batch.cloud_index, point_index), target)
        mu, log_var = model.encode(target, condition, anchor, data.grasp_type[rows])
        mus.append(mu)
        log_vars.append(log_var)
        decoded.append(rotate_grasps(model.generate(mu, condition, anchor, clouds, batch.cloud_index, data.grasp_type[rows]), grasp_turn.transpose(1, 2)))
        grasp_ids.append(batch.grasp_index)
        local.append(condition)
    # batches group grasps by cloud: put the rows back in the order of ``index``
    row_of = {int(g): r for r, g in enumerate(np.concatenate(grasp_ids))} if grasp_ids else {}
    take = torch.as_tensor([row_of[int(g)] for g in np.asarray(index)], dtype=torch.long)
    if not grasp_ids:
        empty = torch.zeros(0, model.config.latent_dim)
        return empty, empty, torch.zeros(0, data.pose_features.shape[1]), torch.zeros(0, model.config.condition_dim)
    return torch.cat(mus)[take], torch.cat(log_vars)[take], torch.cat(decoded)[take], torch.cat(local)[take]


def fit_training_codes(model: GraspCVAE, data: TrainingData, index: np.ndarray, config: TrainConfig) -> dict[str, float]:
    """Store the training grasps' codes (with their conditions, clouds and types) in ``model`` (for aggregate-prior
    sampling); return the fit rung's pose errors.

    The errors are those of the encoder-mean reconstructions of grasps ``index``: median
    palm rotation error (deg), median palm translation error (mm), mean joint error (rad).
    """
    mu, log_var, decoded, condition = encode_training_grasps(model, data, index, config)
    index_tensor = torch.as_tensor(np.asarray(index), dtype=torch.long, device=data.grasp_type.device)
    model.set_latent_codes(mu, log_var, condition, torch.as_tensor(data.cloud_key[np.asarray(index)], dtype=torch.long),
                           data.grasp_type[index_tensor])
    rotation, translation, joints = pose_errors(features_to_pose(decoded), features_to_pose(data.pose_features[torch.as_tensor(index)]))
    return {
        "grasps": int(len(index)),
        "rotation_error_deg_median": float(rotation.median()) if len(index) else math.nan,
        "translation_error_mm_median": float(translation.median()) if len(index) else math.nan,
        "joint_error_rad_mean": float(joints.mean()) if len(index) else math.nan,
    }

