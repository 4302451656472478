"""Stage ``train_cvae``: train the PointNet + CVAE on lift-validated grasps of training objects.

Writes ``cvae.pt`` (state dict + configs, loads with ``torch.load(weights_only=True)``),
``history.csv`` (every loss term per epoch, train and validation) and
``training_curves.png`` into ``--out-dir``; progress per epoch goes to the log.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np
import pandas as pd

from dexlite_pipeline.config import from_section, parse_config_json
from dexlite_pipeline.curate import IMPORTED_ORIGIN
from dexlite_pipeline.io.atomic import atomic_path
from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store
from dexlite_pipeline.model.training import LOSS_TERMS, TrainConfig
from dexlite_pipeline.objects.assets import CATALOG_NAME, CATALOG_REQUIRED_COLUMNS, read_object_table

log = logging.getLogger("dexlite.train_cvae")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections seed, device, energy, train (canonical JSON)")
    parser.add_argument("--lift", action="append", required=True, help="a lift-validated grasp shard (repeatable)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir with catalog.parquet (repeatable)")
    parser.add_argument("--out-dir", required=True, help="where cvae.pt, history.csv and training_curves.png go")


def object_splits(objects_dirs: list[str]) -> dict[str, str]:
    """Object id -> split ('train' / 'heldout') from the catalogs of the objects dirs (first one wins)."""
    splits: dict[str, str] = {}
    for d in objects_dirs:
        path = Path(d) / CATALOG_NAME
        if not path.exists():
            log.warning("%s: no catalog, its objects count as of unknown split and are not trained on", path)
            continue
        catalog = read_object_table(path, "object catalog", (*CATALOG_REQUIRED_COLUMNS, "split"), "prepare_objects")
        ok = catalog["status"] == "ok"
        for oid, split in zip(catalog["object_id"][ok], catalog["split"][ok]):
            splits.setdefault(str(oid), str(split))
    return splits


def read_lift_shards(paths: list[str]) -> GraspSet:
    """All lift shards as one set (only the arrays training needs, so shards may differ in extras).

    ``contact_index`` (the contacts seed synthesis made) is kept for seed grasps and set to
    -1 for imported ones, so the loss searches contacts for those: an imported grasp's
    ``contact_index`` is the four pads nearest the surface that curation scored it at, not
    contacts it was made with (on real DexGraspNet grasps those give E_fc ≈ 10).
    """
    keep = ("hand_pose", "object_id", "scale", "lift_success")
    sets = []
    for p in paths:
        grasps = read_grasp_store(p)
        if len(grasps) and "lift_success" not in grasps.arrays:
            raise ValueError(f"{p}: grasp store has no lift_success array (not a lift_validate output)")
        if len(grasps):
            arrays = {k: grasps.arrays[k] for k in keep}
            contacts = np.array(grasps.arrays.get("contact_index", np.full((len(grasps), 4), -1)), dtype=np.int64)
            imported = np.asarray(grasps.arrays.get("origin", np.full(len(grasps), "", dtype=object)) == IMPORTED_ORIGIN, bool)
            contacts[imported] = -1
            arrays["contact_index"] = contacts
            sets.append(GraspSet(arrays, {}))
    return GraspSet.concatenate(sets)


def plot_history(history: pd.DataFrame, path: Path) -> None:
    """One panel per loss term (and the total), train and validation against the epoch."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = ("total", *LOSS_TERMS)
    fig, axes = plt.subplots(3, 3, figsize=(12, 9), sharex=True)
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
    fig.suptitle("CVAE training (per-epoch means)")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=90, format="png")
    plt.close(fig)


def run(args: argparse.Namespace) -> int:
    import torch

    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.energy.grasp_energy import EnergyConfig, GraspEnergy
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.model.checkpoint import save_checkpoint
    from dexlite_pipeline.model.data import TrainingDataError, build_training_data, select_training_grasps, split_validation
    from dexlite_pipeline.model.training import fit_training_codes, grasp_energy_terms, train_cvae
    from dexlite_pipeline.objects.assets import available_object_ids, load_asset

    cfg = parse_config_json(args.config_json)
    config = from_section(TrainConfig, cfg.get("train"), "config.train")
    seed = int(cfg.get("seed", 0))
    device = resolve_device(cfg.get("device", "auto"))
    out_dir = Path(args.out_dir)

    splits = object_splits(args.objects)
    train_ids = {oid for oid, split in splits.items() if split == "train"}
    lifted = read_lift_shards(args.lift)
    grasps, excluded = select_training_grasps(lifted, train_ids, available_object_ids(args.objects))
    if len(grasps) < config.min_grasps:
        raise TrainingDataError(
            f"{', '.join(args.lift)}: {len(grasps)} lift-successful grasps of training objects, "
            f"train.min_grasps is {config.min_grasps} (excluded: {excluded or 'none'})"
        )
    object_ids = sorted(set(grasps.object_id.tolist()))
    assets = [load_asset(args.objects, oid) for oid in object_ids]
    hand = ShadowHand(device)
    data = build_training_data(grasps, assets, hand, device)
    spen_margin_m = from_section(EnergyConfig, cfg.get("energy"), "config.energy").self_penetration_margin_m
    energy = GraspEnergy.from_assets(hand, assets, EnergyConfig(object_points=config.energy_object_points, self_penetration_margin_m=spen_margin_m))
    train_index, val_index = split_validation(len(grasps), config.validation_fraction, seed)

    def report(row: dict) -> None:
        val = f" val {row['val_total']:.4g} (recon {row['val_recon']:.4g})" if "val_total" in row else ""
        log.info(
            "epoch %d step %d %.1fs: train %.4g (recon %.4g kl %.4g fc %.4g dis %.4g pen %.4g spen %.4g joints %.4g)%s",
            row["epoch"], row["step"], row["seconds"], row["train_total"], row["train_recon"], row["train_kl"],
            row["train_fc"], row["train_dis"], row["train_pen"], row["train_spen"], row["train_joints"], val,
        )

    energy_terms = grasp_energy_terms(energy, config.contact_samples, seed)
    result = train_cvae(data, train_index, val_index, config, energy_terms, seed, on_epoch=report)
    fit = fit_training_codes(result.model, data, train_index, config)
    log.info(
        "fit rung (encoder-mean reconstructions of the %d training grasps): median palm rotation error %.2f deg, "
        "translation %.2f mm, mean joint error %.4f rad",
        len(train_index), fit["rotation_error_deg_median"], fit["translation_error_mm_median"], fit["joint_error_rad_mean"],
    )
    history = pd.DataFrame(result.history)
    out_dir.mkdir(parents=True, exist_ok=True)
    with atomic_path(out_dir / "history.csv") as tmp:
        history.to_csv(tmp, index=False)
    plot_history(history, out_dir / "training_curves.png")
    save_checkpoint(
        out_dir / "cvae.pt",
        result.model,
        config,
        {
            "seed": seed,
            "self_penetration_margin_m": spen_margin_m,
            "steps": result.steps,
            "train_grasps": int(len(train_index)),
            "validation_grasps": int(len(val_index)),
            "train_object_ids": object_ids,
            "excluded_grasps": excluded,
            "torch_version": torch.__version__,
            "fit": fit,
        },
        training_grasps={
            "hand_pose": grasps.hand_pose[train_index],
            "object_id": grasps.object_id[train_index],
            "scale": grasps.scale[train_index],
        },
    )
    log.info("wrote %s (%d steps, %d grasps of %d objects)", out_dir / "cvae.pt", result.steps, len(grasps), len(object_ids))
    return 0
