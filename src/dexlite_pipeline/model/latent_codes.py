"""Which training codes new grasps decode from: the latent priors of the CVAE's sampling (``model.sampling``).

A CVAE trained with a small KL weight keeps a distinct code per training grasp (stored with the model), and sampling
draws its latents near those codes: from all of them (``aggregate``), from those of the training clouds whose PointNet
feature is nearest the new object's (``neighbours``), each cloud preferring codes it drew less (``debiased_codes``),
and, for a model conditioned on grasp types, only from the codes of the type asked of each grasp (``code_type_mask``).
"""

from __future__ import annotations

import numpy as np
import torch

from dexlite_pipeline.model.config import LATENT_PRIORS
from dexlite_pipeline.model.network import GraspCVAE


def sample_latents(
    model: GraspCVAE,
    count: int,
    generator: torch.Generator,
    prior: str = "standard",
    temperature: float = 1.0,
    global_feature: torch.Tensor | None = None,
    neighbour_clouds: int = 1,
    cloud_index: torch.Tensor | None = None,
    type_mask: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor | None]:
    """(count, latent) latents for new grasps, and which training code each came from (None for ``standard``).

    - ``standard``: z ~ N(0, I), the VAE's nominal prior;
    - ``aggregate``: z ~ q(z) = mean_i N(mu_i, sigma_i^2) over the training grasps' codes
      (stored with the model): a CVAE trained with a small KL weight keeps a distinct code per
      grasp, and those codes do not fill N(0, I), so nominal-prior latents decode to poses
      unlike any grasp, while the aggregate posterior is where the decoder was trained;
    - ``neighbours``: the aggregate over the codes of the training clouds (object and scale)
      whose global feature is nearest the new cloud's (``global_feature`` (count, F), the
      ``neighbour_clouds`` nearest): a conditional prior p(z | object) read off the training
      data. On a training object its own cloud is the nearest, so its own grasps' codes are among those drawn.
    ``temperature`` scales the noise (of the prior, or of each code's posterior).
    With ``cloud_index`` (count,) the codes are drawn one row at a time, a code's weight divided
    by (count + 1) where count is how often earlier rows of the same cloud drew it (``debiased_codes``):
    a cloud's grasps then use different training codes before any code repeats.
    ``type_mask`` (count, N) bool: the codes each row may draw (those of its requested grasp type; ``code_type_mask``).
    """
    device = next(model.parameters()).device
    if prior == "standard":
        return torch.randn(count, model.config.latent_dim, generator=generator).to(device) * temperature, None
    if prior not in LATENT_PRIORS:
        raise ValueError(f"latent prior {prior!r} is not one of {', '.join(LATENT_PRIORS)}")
    codes_mu, codes_log_var = model.latent_codes
    if len(codes_mu) == 0:
        raise ValueError(f"latent prior {prior!r} needs a model saved with its training codes (train it with this version)")
    if prior == "neighbours":
        weights = neighbour_weights(model, global_feature, neighbour_clouds, type_mask)
    else:
        weights = torch.ones(count, len(codes_mu), device=device) if type_mask is None else type_mask.to(device).float()
    if cloud_index is None:
        pick = torch.multinomial(weights.cpu(), 1, generator=generator)[:, 0].to(device)
    else:
        pick = debiased_codes(weights.cpu(), cloud_index.cpu(), generator).to(device)
    noise = torch.randn(count, model.config.latent_dim, generator=generator).to(device)
    return codes_mu[pick] + temperature * torch.exp(0.5 * codes_log_var[pick]) * noise, pick


def debiased_codes(weights: torch.Tensor, cloud_index: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """(B,) training codes drawn row by row from ``weights`` (B, N), each divided by (count + 1), count = how often
    earlier rows of the same cloud (``cloud_index`` (B,)) drew that code: Dex1B's inverse-frequency rule over codes.

    Clouds are drawn one after another (rows of a cloud in order); each draw runs over the codes its cloud's rows
    can reach at all (weight > 0: with the ``neighbours`` prior the few hundred codes of the nearest training
    clouds, not every code of the model), so a draw costs what its cloud's neighbourhood holds.
    """
    pick = torch.zeros(len(weights), dtype=torch.long)
    for cloud in torch.unique(cloud_index).tolist():
        rows = torch.nonzero(cloud_index == cloud)[:, 0]
        block = weights[rows]
        support = torch.nonzero((block > 0).any(dim=0))[:, 0]
        if len(support) == 0:
            raise ValueError(f"cloud {cloud}: no training code has a positive weight")
        block = block[:, support]
        used = torch.zeros(len(support))
        for place, row in enumerate(rows.tolist()):
            local = int(torch.multinomial(block[place] / (used + 1.0), 1, generator=generator))
            pick[row] = support[local]
            used[local] += 1.0
    return pick


def neighbour_weights(
    model: GraspCVAE, global_feature: torch.Tensor | None, neighbour_clouds: int, type_mask: torch.Tensor | None = None
) -> torch.Tensor:
    """(B, N) 1 for the codes on the ``neighbour_clouds`` training clouds nearest each new cloud's global feature, else 0.

    With ``type_mask`` (B, N) only the codes it allows count, and the nearest clouds are taken among those holding one."""
    if global_feature is None or len(model.codes_condition) != len(model.codes_mu) or len(model.codes_cloud) != len(model.codes_mu):
        raise ValueError("latent prior 'neighbours' needs a model saved with its codes' conditions and clouds")
    cloud_feature, code_cloud = training_cloud_features(model)
    distance = feature_distances(global_feature, cloud_feature.to(global_feature.device))  # (B, clouds)
    if type_mask is not None:
        type_mask = type_mask.to(distance.device)
        holds = torch.zeros_like(distance).index_add_(1, code_cloud.to(distance.device), type_mask.float()) > 0  # (B, clouds)
        distance = distance.masked_fill(~holds, float("inf"))
    nearest = distance.topk(min(neighbour_clouds, len(cloud_feature)), dim=1, largest=False).indices  # (B, k)
    chosen = torch.zeros_like(distance).scatter_(1, nearest, 1.0)[:, code_cloud]
    return chosen if type_mask is None else chosen * type_mask.float()


def code_type_mask(model: GraspCVAE, grasp_type: np.ndarray | None) -> torch.Tensor | None:
    """(B, N) whether each training code is of the type asked of each row (``grasp_type`` (B,) vocabulary columns), or
    None when the model reads no type (every code may serve every row). ValueError when a row's type has no code."""
    if grasp_type is None or not model.type_inputs or not len(model.codes_mu):
        return None
    wanted = torch.as_tensor(np.asarray(grasp_type), dtype=torch.long, device=model.codes_type.device)
    mask = model.codes_type[None, :] == wanted[:, None]
    missing = sorted({model.grasp_types[int(t)] for t in wanted[~mask.any(dim=1)].tolist()})
    if missing:
        raise ValueError(f"the model holds no training code of grasp type {', '.join(missing)}")
    return mask


def training_cloud_features(model: GraspCVAE) -> tuple[torch.Tensor, torch.Tensor]:
    """(clouds, W) the global PointNet feature of each training cloud (object and scale) the model's codes were
    encoded on, and (N,) each code's cloud row."""
    width = model.config.pointnet_widths[-1]
    clouds, code_cloud = torch.unique(model.codes_cloud, return_inverse=True)
    cloud_feature = torch.zeros(len(clouds), width, device=model.codes_condition.device).index_add_(
        0, code_cloud, model.codes_condition[:, :width]
    ) / torch.bincount(code_cloud, minlength=len(clouds)).clamp(min=1)[:, None].to(model.codes_condition.dtype)
    return cloud_feature, code_cloud


def feature_distances(feature: torch.Tensor, cloud_feature: torch.Tensor) -> torch.Tensor:
    """(B, clouds) Euclidean distances; exact differences: the matrix-product form of cdist cancels catastrophically
    for features this large, and a training cloud must find itself at distance 0."""
    return torch.cdist(feature, cloud_feature, compute_mode="donot_use_mm_for_euclid_dist")
