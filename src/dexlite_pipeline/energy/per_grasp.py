"""Energy terms of a whole grasp set (any origin: seed, DexGraspNet import, CVAE samples)."""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
import torch

from dexlite_pipeline.energy.config import EnergyConfig, EnergyWeights
from dexlite_pipeline.energy.grasp_energy import CONTACT_COUNT, TERM_NAMES, GraspEnergy, max_scale_by_object
from dexlite_pipeline.hand.model import ShadowHand
from dexlite_pipeline.io.grasp_store import GraspSet, invalid_grasp_reasons
from dexlite_pipeline.objects.assets import ObjectAssetError, load_asset

log = logging.getLogger(__name__)

RESULT_ARRAYS = (*TERM_NAMES, "E_total", "penetration_mm", "contact_distance_mm")


def evaluate_grasp_energies(
    grasps: GraspSet,
    objects_dirs,
    weights: EnergyWeights | None = None,
    device: torch.device | str = "cpu",
    batch_size: int = 256,
    config: EnergyConfig = EnergyConfig(),
    hand: ShadowHand | None = None,
    contact_samples: int = 0,
) -> dict[str, np.ndarray]:
    """Per-grasp E_fc, E_dis, E_pen, E_spen, E_joints, E_total, penetration_mm, contact_distance_mm.

    Contacts: a ``contact_index`` (N, 4) array in ``grasps`` is used as given where a row
    has four non-negative indices (rows with -1: no contacts given). Otherwise
    the four candidates closest to the object surface (smallest |d|: the least E_dis any
    choice gives, the contacts the pose actually makes). With ``contact_samples`` > 0,
    that set and as many random sets favouring pads near the surface are searched for the
    lowest w_fc·E_fc + w_dis·E_dis (deterministic): the four nearest often lie on one pad,
    whose parallel normals read as no force closure. The chosen ``contact_index`` is
    returned too.
    ``weights`` (default ``config.weights``) only affect ``E_total``.
    A grasp with a non-finite pose or scale, or whose object has no usable asset, gets NaN
    values and its reason in ``energy_failure_reason``; the others are evaluated.
    """
    config = dataclasses.replace(config, weights=weights or config.weights)
    device = torch.device(device)
    hand = hand if hand is not None and hand.device == device else ShadowHand(device)
    n = len(grasps)
    out = {name: np.full(n, np.nan, np.float32) for name in RESULT_ARRAYS}
    out["contact_index"] = np.full((n, CONTACT_COUNT), -1, np.int64)
    out["energy_failure_reason"] = np.full(n, "", dtype=object)
    given_contacts = grasps.arrays.get("contact_index")
    has_given = np.zeros(n, bool) if given_contacts is None else (np.asarray(given_contacts) >= 0).all(axis=1)
    invalid = invalid_grasp_reasons(grasps)
    out["energy_failure_reason"][invalid != ""] = invalid[invalid != ""]

    assets_by_resolution: dict[tuple, list] = {}
    for object_id in sorted(set(map(str, grasps.object_id))):
        try:
            asset = load_asset(objects_dirs, object_id)
        except ObjectAssetError as exc:  # load_asset reports every unreadable asset as this
            log.warning("energy: %s", exc)
            out["energy_failure_reason"][grasps.object_id == object_id] = f"object asset unusable: {exc}"
            continue
        assets_by_resolution.setdefault(asset.sdf.shape, []).append(asset)

    object_ids = np.asarray([str(o) for o in grasps.object_id])
    generator = torch.Generator().manual_seed(0)
    for assets in assets_by_resolution.values():
        energy = GraspEnergy.from_assets(hand, assets, config, max_scale=max_scale_by_object(grasps.object_id, grasps.scale))
        rows = np.nonzero(np.isin(object_ids, energy.object_ids) & (invalid == ""))[0]
        for start in range(0, len(rows), batch_size):
            idx = rows[start : start + batch_size]
            pose = torch.as_tensor(grasps.hand_pose[idx], dtype=hand.dtype, device=device)
            scale = torch.as_tensor(grasps.scale[idx], dtype=hand.dtype, device=device)
            object_index = energy.object_index(object_ids[idx])
            given = torch.as_tensor(has_given[idx], device=device)
            contacts = torch.as_tensor(given_contacts[idx], dtype=torch.long, device=device).clamp(min=0) if given.any() else None
            if not given.all():
                chosen = energy.nearest_contacts(hand.forward(pose), object_index, scale)
                if contact_samples:
                    chosen = energy.best_contacts(pose, object_index, scale, chosen, contact_samples, generator)
                contacts = chosen if contacts is None else torch.where(given[:, None], contacts, chosen)
            with torch.no_grad():
                result = energy(pose, object_index=object_index, scale=scale, contact_index=contacts, exact_penetration=True)
            for name, value in result.terms.items():
                out[name][idx] = value.cpu().numpy()
            out["E_total"][idx] = result.total.cpu().numpy()
            out["penetration_mm"][idx] = result.penetration_mm.cpu().numpy()
            out["contact_distance_mm"][idx] = result.contact_distance_mm.cpu().numpy()
            out["contact_index"][idx] = result.contact_index.cpu().numpy()
    return out


def energy_summary_lines(arrays: dict) -> list[str]:
    """Human-readable medians and the threshold pass fraction over the evaluated grasps."""
    evaluated = arrays["energy_failure_reason"] == ""
    lines = [f"grasps: {len(evaluated)}, evaluated: {int(evaluated.sum())}"]
    if evaluated.any():
        for name in ("E_fc", "E_dis", "E_pen", "E_spen", "E_joints", "penetration_mm", "contact_distance_mm"):
            values = arrays[name][evaluated]
            lines.append(f"{name:>20}: median {np.median(values):.4g}  p90 {np.percentile(values, 90):.4g}")
        lines.append(f"pass energy thresholds: {100 * arrays['passes_energy_thresholds'][evaluated].mean():.1f}%")
    return lines


def store_energies(grasps_path: str, objects_dirs: list[str], energy_config, thresholds, device="cpu", batch_size: int = 256, contact_samples: int = 0,
                   hand=None):
    """The grasps of a store with their energy terms, ``passes_energy_thresholds`` (``thresholds``:
    an ``EnergyThresholds``) and ``energy_failure_reason`` added, and the attributes recording how. ``hand``: the model
    of the hand the store's poses are of, on ``device`` (None: the Shadow Hand)."""
    from dexlite_pipeline.config import json_ready
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.io.grasp_store import read_grasp_store

    if batch_size < 1:
        raise ValueError(f"--batch-size must be positive, got {batch_size}")
    grasps = read_grasp_store(grasps_path)
    arrays = evaluate_grasp_energies(
        grasps, objects_dirs, device=resolve_device(device), batch_size=batch_size, config=energy_config, hand=hand, contact_samples=contact_samples
    )
    arrays["passes_energy_thresholds"] = thresholds.passes(arrays) & (arrays["energy_failure_reason"] == "")
    grasps.arrays.update(arrays)
    attrs = {"energy": {"source": str(grasps_path), "config": json_ready(energy_config), "thresholds": json_ready(thresholds), "contact_samples": contact_samples}}
    return grasps, attrs
