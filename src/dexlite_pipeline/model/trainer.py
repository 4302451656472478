"""Training a grasp model from the pipeline's data: the ``train_cvae`` stage's work.

Takes the lift-validated grasps of training objects from the lift shards, builds the
training data (clouds, associated points), trains the PointNet + CVAE (``model.training``),
measures the learning ladder's fit rung on the training grasps, and writes the model file
(``cvae.pt``), the per-epoch history (CSV) and a plot of the loss curves.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from dexlite_pipeline.atomic import atomic_path
from dexlite_pipeline.curation.config import IMPORTED_ORIGIN
from dexlite_pipeline.io.grasp_store import GRASP_TYPE, GraspSet, grasp_types, read_grasp_store
from dexlite_pipeline.model.config import LOSS_TERMS, SURFACE_TERMS, TrainConfig
from dexlite_pipeline.model.hand_match import shards_hand
from dexlite_pipeline.model.training import TrainingResult

log = logging.getLogger(__name__)


def read_lift_shards(paths: list[str], hand: str | None = None) -> GraspSet:
    """All lift shards as one set (only the arrays training needs, so shards may differ in extras).

    The shards must be of one hand (``grasp_store.check_one_hand``) and, when ``hand`` (config key ``hand``) is given, of
    that hand: ``GraspStoreError`` in one line naming a shard and both hands otherwise. The set's attributes are the
    hand's record (``hand``, ``joint_names``; none when no shard holds grasps).

    ``contact_index`` (the contacts their optimization from scratch chose) is kept for optimized grasps and set to
    -1 for imported ones, so the loss searches contacts for those: an imported grasp's
    ``contact_index`` is the four pads nearest the surface that curation scored it at, not
    contacts it was made with. ``grasp_type`` is each grasp's type (power for a shard without types).
    """
    keep = ("hand_pose", "object_id", "scale", "lift_success")
    sets, named_attrs = [], []
    for path in paths:
        grasps = read_grasp_store(path)
        named_attrs.append((path, grasps.attrs))
        if len(grasps) and "lift_success" not in grasps.arrays:
            raise ValueError(f"{path}: grasp store has no lift_success array (not a lift_validate output)")
        if len(grasps):
            arrays = {k: grasps.arrays[k] for k in keep}
            contacts = np.array(grasps.arrays.get("contact_index", np.full((len(grasps), 4), -1)), dtype=np.int64)
            imported = np.asarray(grasps.arrays.get("origin", np.full(len(grasps), "", dtype=object)) == IMPORTED_ORIGIN, bool)
            contacts[imported] = -1
            arrays["contact_index"] = contacts
            arrays[GRASP_TYPE] = grasp_types(grasps)
            sets.append(GraspSet(arrays, {}))
    record = shards_hand(named_attrs, hand)
    return GraspSet.concatenate(sets, record if sets else None)


def training_object_subset(object_ids: set[str], count: int, seed: int) -> set[str]:
    """A seeded choice of ``count`` of ``object_ids`` (all of them when ``count`` is 0 or not smaller).

    The choice for a smaller count is contained in the choice for a larger one (one seeded
    order, cut at ``count``), so a learning curve adds objects without swapping any.
    """
    ordered = sorted(object_ids)
    if count <= 0 or count >= len(ordered):
        return set(ordered)
    order = np.random.default_rng([seed, 0x0B1EC75]).permutation(len(ordered))
    return {ordered[i] for i in order[:count]}


def training_family_subset(object_ids: set[str], count: int, seed: int) -> set[str]:
    """The objects of ``object_ids`` in a seeded choice of ``count`` of their families (``objects.family.object_family``;
    all of them when ``count`` is 0 or not smaller). Nested like ``training_object_subset``: the families chosen for a
    smaller count are among those chosen for a larger one (one seeded order of the family names, cut at ``count``)."""
    from dexlite_pipeline.objects.family import object_family

    families = sorted({object_family(oid) for oid in object_ids})
    if count <= 0 or count >= len(families):
        return set(object_ids)
    order = np.random.default_rng([seed, 0xFA3111E5]).permutation(len(families))
    chosen = {families[i] for i in order[:count]}
    return {oid for oid in object_ids if object_family(oid) in chosen}


def grasps_per_object_subset(object_ids: np.ndarray, count: int, seed: int) -> np.ndarray:
    """(K,) sorted row indices: a seeded choice of at most ``count`` rows per object of ``object_ids`` (all when 0).

    One seeded order of all rows; an object keeps its first ``count`` rows in it, so the choice for a
    smaller count is contained in the choice for a larger one (a learning curve adds grasps without swapping any).
    """
    ids = np.asarray(object_ids).astype(str)
    if count <= 0 or not len(ids):
        return np.arange(len(ids))
    order = np.random.default_rng([seed, 0x6A5B5]).permutation(len(ids))
    place = np.empty(len(ids), np.int64)  # each row's place among its object's rows in the seeded order
    seen: dict[str, int] = {}
    for row in order.tolist():
        place[row] = seen.get(ids[row], 0)
        seen[ids[row]] = place[row] + 1
    return np.flatnonzero(place < count)


def uses_energies(train: TrainConfig, table: bool) -> bool:
    """Whether the loss has a weighted energy term that needs the objects' SDF grids and meshes (config
    ``train.energy_weights``; E_table only on a table)."""
    return train.uses_mesh_energies(table)


def unbuilt_energy_terms(*args, **kwargs):
    """The loss's energy terms when every energy weight is 0: ``training.batch_loss`` never calls them."""
    raise RuntimeError("energy terms were not built: every train.energy_weights is 0")


@dataclass
class TrainedModel:
    """A trained model with what its file records: the run's facts and the grasps it was fitted to."""

    result: TrainingResult
    facts: dict  # seed, steps, grasp counts, object ids, exclusions, fit rung, versions (JSON-ready)
    training_grasps: dict  # hand_pose (N, 6 + J), object_id (N,), scale (N,), grasp_type (N,) of the training split
    train: TrainConfig  # config section ``train`` it was trained with


def _log_epoch(row: dict) -> None:
    val = f" val {row['val_total']:.4g} (recon {row['val_recon']:.4g})" if "val_total" in row else ""
    surface = "".join(f" {term} {row[f'train_{term}']:.4g}" for term in SURFACE_TERMS if f"train_{term}" in row)
    log.info(
        "epoch %d step %d %.1fs: train %.4g (recon %.4g kl %.4g fc %.4g dis %.4g pen %.4g spen %.4g joints %.4g%s)%s",
        row["epoch"], row["step"], row["seconds"], row["train_total"], row["train_recon"], row["train_kl"],
        row["train_fc"], row["train_dis"], row["train_pen"], row["train_spen"], row["train_joints"], surface, val,
    )


def train_from_lift_shards(
    lift_paths: list[str], objects_dirs: list[str], *, train: TrainConfig, self_penetration_margin_m: float, table: bool, seed: int, device: str,
    stability_path: str | None = None, initial_model_path: str | None = None, hand: str = "shadow",
    state_path: str | Path | None = None, state_every_s: float = 300.0,
) -> TrainedModel:
    """Train on the lift-successful grasps of the training objects in ``lift_paths``.

    Raises ``TrainingDataError`` naming the shards when fewer than ``train.min_grasps`` remain.
    The config it reads comes as arguments: section ``train``, ``energy.self_penetration_margin_m`` (m),
    ``scene.table`` (``table``), and the top-level ``seed`` and ``device``. In tabletop mode the loss's energy knows each object's table (resting poses
    from ``stability_path``) and E_table is a loss term with weight ``train.energy_weights.table``.
    ``initial_model_path``: a model file to go on training (warm start) instead of a fresh model.
    ``hand`` (config key ``hand``): the hand the shards' grasps are of (refused otherwise) and the model is for; the
    loss's energies and the grasp rays use its model (``hand.choice.resolve_hand``), the file records it.
    ``state_path``: where the training's state is saved every ``state_every_s`` seconds (at epoch ends) and looked for
    at the start, so that a rerun after an interruption goes on from it (``model.training_state``); None: neither.
    """
    from dexlite_pipeline.tabletop import load_support_planes

    import torch

    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.energy.config import EnergyConfig
    from dexlite_pipeline.energy.grasp_energy import GraspEnergy, max_scale_by_object
    from dexlite_pipeline.hand.choice import hand_record, resolve_hand
    from dexlite_pipeline.model.data import TrainingDataError, build_training_data, select_training_grasps, split_validation
    from dexlite_pipeline.model.surface_terms import surface_terms
    from dexlite_pipeline.model.training import fit_training_codes, grasp_energy_terms, train_cvae, with_surface_terms
    from dexlite_pipeline.model.training_state import TrainingStateFile
    from dexlite_pipeline.objects.assets import available_object_ids, load_asset, object_splits

    settings = train
    device = resolve_device(device)
    record = hand_record(hand)  # an unusable hand: one line before any work
    lifted = read_lift_shards(lift_paths, hand)
    train_ids = {oid for oid, split in object_splits(objects_dirs).items() if split == "train"}
    if settings.max_training_families > 0 or settings.max_training_objects > 0:  # the learning curves: seeded subsets of the
        held = set(lifted.object_id[np.asarray(lifted.arrays["lift_success"], bool)].tolist()) if len(lifted) else set()  # objects with
        train_ids = train_ids & held  # lift-successful grasps, by family and then by object
        if settings.max_training_families > 0:
            train_ids = training_family_subset(train_ids, settings.max_training_families, seed)
        train_ids = training_object_subset(train_ids, settings.max_training_objects, seed)
    grasps, excluded = select_training_grasps(lifted, train_ids, available_object_ids(objects_dirs))
    if settings.max_grasps_per_object > 0:  # the learning curve against grasps per object
        kept = grasps_per_object_subset(grasps.object_id, settings.max_grasps_per_object, seed)
        if len(kept) < len(grasps):
            excluded = {**excluded, "beyond train.max_grasps_per_object": int(len(grasps) - len(kept))}
            log.info("training grasps: %d of %d kept by train.max_grasps_per_object = %d", len(kept), len(grasps), settings.max_grasps_per_object)
        grasps = grasps.select(kept)
    if len(grasps) < settings.min_grasps:
        raise TrainingDataError(
            f"{', '.join(lift_paths)}: {len(grasps)} lift-successful grasps of training objects, "
            f"train.min_grasps is {settings.min_grasps} (excluded: {excluded or 'none'})"
        )
    object_ids = sorted(set(grasps.object_id.tolist()))
    assets = [load_asset(objects_dirs, oid) for oid in object_ids]
    hand_model = resolve_hand(hand, device)
    initial_model = None
    if initial_model_path is not None:
        from dexlite_pipeline.model.checkpoint import load_checkpoint

        initial_model = load_checkpoint(initial_model_path, device, hand=record)[0]
    # a warm start keeps its model's grasp types; a fresh model is conditioned on the grasps' own
    data = build_training_data(grasps, assets, hand_model, device, initial_model.type_vocabulary if initial_model is not None else None, record)
    margin_m = self_penetration_margin_m
    planes = load_support_planes(table, stability_path)
    if uses_energies(settings, table=planes is not None):
        energy = GraspEnergy.from_assets(
            hand_model, assets, EnergyConfig(object_point_spacing_m=settings.energy_point_spacing_m, self_penetration_margin_m=margin_m),
            support_planes=planes, max_scale=max_scale_by_object(grasps.object_id, grasps.scale),
        )
        energy_terms = grasp_energy_terms(energy, settings.contact_samples, seed)
    else:  # every energy weight 0 (the default): the loss never scores a decoded pose, so no SDF bank or point sets
        energy_terms = unbuilt_energy_terms
    if settings.surface_terms():  # read off the clouds' surface samples: no memory per object beyond them
        surface = surface_terms(hand_model, data.clouds, settings.surface_terms(), training_grasps=len(data.pose_features))
        energy_terms = with_surface_terms(energy_terms, surface, mesh=uses_energies(settings, table=planes is not None))
    del assets  # the SDF grids (~1 MB an object): training reads the clouds ``data`` holds
    train_index, val_index = split_validation(len(grasps), settings.validation_fraction, seed)
    state_file = None
    if state_path is not None:
        state_file = TrainingStateFile(Path(state_path), state_every_s, context={
            "hand": record, "self_penetration_margin_m": margin_m, "table": planes is not None,
            "support_planes": None if planes is None else {oid: repr(planes.planes.get(oid)) for oid in object_ids}})
    result = train_cvae(
        data, train_index, val_index, settings, energy_terms, seed, on_epoch=_log_epoch, table=planes is not None, initial_model=initial_model,
        state_file=state_file,
    )
    fit = fit_training_codes(result.model, data, train_index, settings)
    log.info(
        "fit rung (encoder-mean reconstructions of the %d training grasps): median palm rotation error %.2f deg, "
        "translation %.2f mm, mean joint error %.4f rad",
        len(train_index), fit["rotation_error_deg_median"], fit["translation_error_mm_median"], fit["joint_error_rad_mean"],
    )
    facts = {
        "seed": seed,
        "self_penetration_margin_m": margin_m,
        "steps": result.steps,
        "resumed_after_epoch": result.resumed_after_epoch,  # > 0: a saved training state was loaded (process CPU counts omit the earlier run)
        "train_grasps": int(len(train_index)),
        "validation_grasps": int(len(val_index)),
        "train_object_ids": object_ids,
        "excluded_grasps": excluded,
        "torch_version": torch.__version__,
        "fit": fit,
        "train_grasp_types": {name: int(count) for name, count in zip(*np.unique(grasps.arrays[GRASP_TYPE][train_index], return_counts=True))},
    }
    training_grasps = {"hand_pose": grasps.hand_pose[train_index], "object_id": grasps.object_id[train_index], "scale": grasps.scale[train_index],
                       "grasp_type": grasps.arrays[GRASP_TYPE][train_index]}
    return TrainedModel(result=result, facts=facts, training_grasps=training_grasps, train=settings)


def plot_history(history: pd.DataFrame, path: Path) -> None:
    """One panel per loss term (and the total), train and validation against the epoch (PNG, written atomically)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = ("total", *LOSS_TERMS, *[term for term in SURFACE_TERMS if f"train_{term}" in history.columns])
    fig, axes = plt.subplots(math.ceil(len(names) / 3), 3, figsize=(12, 3 * math.ceil(len(names) / 3)), sharex=True, squeeze=False)
    for ax, name in zip(axes.flat, names):
        for split, style in (("train", "-"), ("val", "--")):
            column = f"{split}_{name}"
            if column in history.columns:
                ax.plot(history["epoch"], history[column], style, label=split)
        ax.set_title(name)
        if (history.filter(like=f"_{name}") > 0).all().all():
            ax.set_yscale("log")
        ax.legend(fontsize=8)
    for ax in axes.flat[len(names):]:
        ax.axis("off")
    for ax in axes[-1]:
        ax.set_xlabel("epoch")
    fig.suptitle("generator training (per-epoch means; flow: recon is the velocity error)")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=90, format="png")
    plt.close(fig)


def write_trained_model(trained: TrainedModel, model_path: str | Path, history_path: str | Path, curves_path: str | Path) -> None:
    """The model file (weights, configs, facts, training grasps), the history CSV and the loss-curve plot."""
    from dexlite_pipeline.model.checkpoint import save_checkpoint

    history = pd.DataFrame(trained.result.history)
    for path in (model_path, history_path, curves_path):
        Path(path).parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(history_path) as tmp:
        history.to_csv(tmp, index=False)
    plot_history(history, Path(curves_path))
    save_checkpoint(model_path, trained.result.model, trained.train, trained.facts, training_grasps=trained.training_grasps)
