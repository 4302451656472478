"""Point-wise sampling of an ``SdfBank`` without copying grids per grasp.

``SdfBank.signed_distance`` gathers from ``volumes[object_index]``, which copies one full
grid (G³ values) per grasp row; for the energy's flat lists of (grasp, point) pairs that
would be one grid per point. This samples the same trilinear interpolant (same sign,
normal and outside-the-grid convention as the bank) by indexing the flattened bank
directly, for points of any batch shape with a per-point object and scale.
"""

from __future__ import annotations

import torch

from dexlite_pipeline.objects.assets import SdfBank


def sample_signed_distance(
    bank: SdfBank, points_m: torch.Tensor, object_index: torch.Tensor, scale: torch.Tensor, with_normal: bool = True
) -> tuple[torch.Tensor, torch.Tensor | None]:
    """Signed distance in metres (positive inside) and outward unit normal at ``points_m`` (..., 3).

    ``object_index`` and ``scale`` have the points' batch shape (or broadcast to it).
    Differentiable with respect to the points. ``with_normal=False`` skips the normal (None).
    """
    g = bank.resolution
    shape = points_m.shape[:-1]
    object_index = object_index.expand(shape)
    s = scale.to(points_m.dtype).expand(shape)[..., None]
    local = points_m / s
    gmin = bank.grid_min[object_index]
    h = bank.voxel_size[object_index][..., None]
    u = (local - gmin) / h
    u_clamped = u.clamp(0.0, g - 1 - 1e-4)
    outside = ((u - u_clamped) * h).norm(dim=-1)
    base = u_clamped.detach().floor().long()
    frac = u_clamped - base
    flat = bank.volumes.reshape(-1)
    origin = object_index * (g * g * g) + (base[..., 0] * g + base[..., 1]) * g + base[..., 2]
    fx, fy, fz = frac.unbind(-1)

    def corner(di: int, dj: int, dk: int) -> torch.Tensor:
        return flat[origin + (di * g + dj) * g + dk]

    c000, c100, c010, c110 = corner(0, 0, 0), corner(1, 0, 0), corner(0, 1, 0), corner(1, 1, 0)
    c001, c101, c011, c111 = corner(0, 0, 1), corner(1, 0, 1), corner(0, 1, 1), corner(1, 1, 1)
    c00 = c000 + (c100 - c000) * fx
    c10 = c010 + (c110 - c010) * fx
    c01 = c001 + (c101 - c001) * fx
    c11 = c011 + (c111 - c011) * fx
    c0 = c00 + (c10 - c00) * fy
    c1 = c01 + (c11 - c01) * fy
    value = c0 + (c1 - c0) * fz
    distance_m = (value - outside) * s[..., 0]
    if not with_normal:
        return distance_m, None
    gx = ((c100 - c000) * (1 - fy) + (c110 - c010) * fy) * (1 - fz) + ((c101 - c001) * (1 - fy) + (c111 - c011) * fy) * fz
    gy = (c10 - c00) * (1 - fz) + (c11 - c01) * fz
    gz = c1 - c0
    inward = torch.stack([gx, gy, gz], dim=-1)
    away = local - (gmin + u_clamped * h)
    direction = torch.where((outside > 0)[..., None], away, -inward)
    normal = torch.nn.functional.normalize(direction, dim=-1)
    return distance_m, normal
