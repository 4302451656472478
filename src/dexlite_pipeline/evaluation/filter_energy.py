"""The equal energy filter's contact-dependent energies: one deterministic contact search for every method.

E_fc and E_dis depend on which four of the hand's 140 contact candidates count as a grasp's
contacts. Optimization from scratch flags ``passes_energy_thresholds`` with the set its optimizer
searched for; the evaluation's energies take the four candidates nearest the surface, which
often lie on one finger pad, whose parallel normals read as no force closure (docs/results.md,
"The equal filter's contacts"). A filter that every method goes through must choose contacts
the same way for every grasp, whoever made it, and without the optimizer's bookkeeping. So,
per grasp:

1. the ``SEARCH_CANDIDATES`` (16) candidates nearest the object surface (|signed distance|);
2. every multiset of four of them (a candidate may count twice, as in the optimizer's own
   sets, which draw with replacement): C(19, 4) = 3,876 sets, each scored as the from-scratch optimizer
   scores its contact sets, w_fc·E_fc + w_dis·E_dis (config ``energy.weights``); the lowest
   wins (the first on ties).

Each grasp's result depends only on its own pose, object and scale (no random draw, no batch
statistic), so a method's filter does not change with the other methods evaluated beside it.
"""

from __future__ import annotations

import itertools
import logging

import numpy as np

log = logging.getLogger(__name__)

SEARCH_CANDIDATES = 16  # candidates nearest the surface searched per grasp: 3,876 four-sets (repeats allowed)
FILTER_CONTACTS = "filter_contact_index"  # (N, 4) the chosen candidates (-1: not computed)
FILTER_ENERGIES = ("filter_E_fc", "filter_E_dis")  # E_fc and E_dis (m) with those contacts; NaN: not computed


def filter_energy_arrays(grasps, objects_dirs, energy_weights, device="cpu", batch_size: int = 64, hand=None) -> dict[str, np.ndarray]:
    """``filter_contact_index``, ``filter_E_fc`` and ``filter_E_dis`` of every grasp (NaN / -1 for invalid grasps or unusable objects).

    ``energy_weights``: the ``EnergyWeights`` whose fc and dis weigh the two terms in the search. ``hand``: the hand
    model of the poses (its contact candidates; None: the Shadow Hand's 140).
    """
    import torch

    from dexlite_pipeline.energy.terms import ForceClosureTerm
    from dexlite_pipeline.evaluation.metrics import invalid_flags
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.objects.assets import ObjectAssetError, SdfBank, load_asset

    n = len(grasps)
    out = {FILTER_CONTACTS: np.full((n, 4), -1, np.int64), **{name: np.full(n, np.nan, np.float32) for name in FILTER_ENERGIES}}
    if n == 0:
        return out
    device = torch.device(device)
    hand = ShadowHand(device) if hand is None else hand
    force_closure = ForceClosureTerm()
    sets = torch.as_tensor(list(itertools.combinations_with_replacement(range(SEARCH_CANDIDATES), 4)), device=device)  # (S, 4)
    object_ids = np.asarray([str(o) for o in grasps.object_id])
    valid = ~invalid_flags(grasps.arrays)
    for object_id in sorted(set(object_ids[valid])):
        try:
            bank = SdfBank([load_asset(objects_dirs, object_id)], device=device, dtype=hand.dtype)
        except ObjectAssetError as exc:
            log.warning("filter energies: %s: %s; its grasps fail the filter", object_id, exc)
            continue
        rows = np.flatnonzero((object_ids == object_id) & valid)
        for start in range(0, len(rows), batch_size):
            idx = rows[start : start + batch_size]
            pose = torch.as_tensor(np.asarray(grasps.hand_pose[idx], np.float32), dtype=hand.dtype, device=device)
            scale = torch.as_tensor(np.asarray(grasps.scale[idx], np.float32), dtype=hand.dtype, device=device)
            with torch.no_grad():
                candidates = hand.contact_candidates(hand.forward(pose))  # (B, 140, 3) metres, object frame
                distance, normal = bank.signed_distance(candidates, torch.zeros(len(idx), dtype=torch.long, device=device), scale)
                gap = distance.abs()
                order = torch.sort(gap, dim=1, stable=True).indices[:, : sets.max() + 1]  # (B, K) the candidates nearest the surface
                chosen = order[:, sets]  # (B, S, 4) candidate indices
                flat = chosen.reshape(len(idx), -1)
                points = torch.gather(candidates, 1, flat[..., None].expand(-1, -1, 3)).reshape(-1, 4, 3)
                normals = torch.gather(normal, 1, flat[..., None].expand(-1, -1, 3)).reshape(-1, 4, 3)
                e_fc = force_closure(points, normals).reshape(len(idx), -1)
                e_dis = torch.gather(gap, 1, flat).reshape(len(idx), -1, 4).sum(-1)
                best = (energy_weights.fc * e_fc + energy_weights.dis * e_dis).argmin(dim=1)
                pick = torch.arange(len(idx), device=device)
            out[FILTER_CONTACTS][idx] = chosen[pick, best].cpu().numpy()
            out["filter_E_fc"][idx] = e_fc[pick, best].cpu().numpy()
            out["filter_E_dis"][idx] = e_dis[pick, best].cpu().numpy()
    return out
