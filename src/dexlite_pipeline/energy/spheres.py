"""A sphere model of the hand's collision shapes, for hand-against-object-SDF queries.

Each capsule becomes spheres of its radius along its axis (spacing r/2, ends included);
each box becomes spheres of its smallest half-extent on a grid in its mid-plane. A sphere
of centre c and radius r penetrates the object by d(c) + r (d positive inside), exact
for the capsule's end caps and wherever the surface is locally flat, and far cheaper than
querying the SDF at the shapes' surface points (Dex1B models the hand by spheres likewise). Each shape also gets its covering gap: how
far its true surface reaches beyond its spheres, so a culling test on spheres stays exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from dexlite_pipeline.hand.model import CAPSULE, ShadowHand


@dataclass
class HandSpheres:
    """Spheres in link frames: centre (K, 3), radius (K,), link (K,), shape (K,); gap per shape (S,)."""

    centre_local: torch.Tensor
    radius: torch.Tensor
    link: torch.Tensor
    shape: torch.Tensor
    shape_gap: torch.Tensor


def _axis_positions(half_extent: float, spacing: float) -> np.ndarray:
    count = max(1, int(math.ceil(2 * half_extent / spacing)) + 1)
    return np.linspace(-half_extent, half_extent, count)


def _shape_sphere_centres(kind: int, size: list[float]) -> tuple[np.ndarray, float]:
    """Sphere centres in the shape frame and their common radius."""
    if kind == CAPSULE:
        radius, half = size[0], size[1]
        z = _axis_positions(half, radius / 2)
        return np.stack([np.zeros_like(z), np.zeros_like(z), z], axis=1), radius
    half = np.asarray(size[:3])
    thin = int(np.argmin(half))
    radius = float(half[thin])
    axes = [a for a in range(3) if a != thin]
    grids = [_axis_positions(max(half[a] - radius, 0.0), radius) for a in axes]
    gu, gv = np.meshgrid(*grids, indexing="ij")
    centres = np.zeros((gu.size, 3))
    centres[:, axes[0]], centres[:, axes[1]] = gu.ravel(), gv.ravel()
    return centres, radius


def _covering_gap(kind: int, size: list[float]) -> float:
    """How far the shape's surface reaches beyond its spheres (max over the surface of distance to the union), m.

    Exact, from the grids of ``_shape_sphere_centres``. Capsule: a point of the cylinder is
    at most half a spacing along the axis from a centre, sqrt(r² + (s/2)²) − r; the end
    caps lie on their spheres. Box (thin half-extent r): along each other axis a point is
    at most d = max(s/2, overhang past the last centre) from the nearest grid line, and
    |thin coordinate| ≤ r, so sqrt(d_u² + d_v² + r²) − r, reached at the corners.
    """
    if kind == CAPSULE:
        radius, half = size[0], size[1]
        z = _axis_positions(half, radius / 2)
        spacing = float(z[1] - z[0]) if len(z) > 1 else 0.0
        return math.hypot(radius, spacing / 2) - radius
    half = np.asarray(size[:3])
    thin = int(np.argmin(half))
    radius = float(half[thin])
    reach = []
    for a in (a for a in range(3) if a != thin):
        grid = _axis_positions(max(half[a] - radius, 0.0), radius)
        spacing = float(grid[1] - grid[0]) if len(grid) > 1 else 0.0
        reach.append(max(spacing / 2, float(half[a] - grid.max())))
    return math.sqrt(reach[0] ** 2 + reach[1] ** 2 + radius**2) - radius


def build_hand_spheres(hand: ShadowHand) -> HandSpheres:
    """The sphere model of ``hand`` and each shape's covering gap."""
    centres, radii, links, shapes = [], [], [], []
    shape_rot = hand.shape_rot.cpu().double().numpy()
    shape_pos = hand.shape_pos.cpu().double().numpy()
    for s in range(len(hand.shape_kind)):
        local, radius = _shape_sphere_centres(int(hand.shape_kind[s]), hand.shape_size[s].tolist())
        centres.append(local @ shape_rot[s].T + shape_pos[s])
        radii += [radius] * len(local)
        links += [int(hand.shape_link[s])] * len(local)
        shapes += [s] * len(local)
    centre = torch.as_tensor(np.concatenate(centres), dtype=torch.float64)
    radius = torch.as_tensor(radii, dtype=torch.float64)
    shape = torch.as_tensor(shapes)

    gaps = [_covering_gap(int(hand.shape_kind[s]), hand.shape_size[s].tolist()) for s in range(len(hand.shape_kind))]
    device, dtype = hand.device, hand.dtype
    return HandSpheres(
        centre_local=centre.to(device, dtype),
        radius=radius.to(device, dtype),
        link=torch.as_tensor(links, device=device),
        shape=shape.to(device),
        shape_gap=torch.as_tensor(gaps, device=device, dtype=dtype),
    )
