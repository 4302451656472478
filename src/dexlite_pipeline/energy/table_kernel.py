"""E_table of a batch in one compiled CPU pass (numba), with its gradient in the link frames.

E_table = Σ over the hand's shapes of max(0, −h), h the height of the shape's lowest point above
the table n·x + offset = 0 (``table_clearance.HandTableClearance``): h = n·c − Σᵢ eᵢ·|n·aᵢ| − r for a
shape of centre c, axes aᵢ (its rotation's columns), half extents eᵢ (a capsule: 0, 0, its half
length) and radius r (a box: 0). For a shape below the table, ∂E/∂c = −n and ∂E/∂aᵢ = eᵢ·sign(n·aᵢ)·n,
carried to the link frame by Rₛ = R·Q, cₛ = R·q + t. The torch version stays the reference and
runs on GPUs.
"""

from __future__ import annotations

import numba
import numpy as np

from dexlite_pipeline.energy.frame_gradient import attach, frame_arrays, wants_gradient


@numba.njit(cache=True, nogil=True)
def _table_depth(rotation, translation, normal, offset, want_gradient, shape_link, shape_rot, shape_pos, half_extent, radius):
    batch, links = rotation.shape[0], rotation.shape[1]
    energy = np.zeros(batch)
    grad_rotation = np.zeros((batch if want_gradient else 0, links, 3, 3))
    grad_translation = np.zeros((batch if want_gradient else 0, links, 3))
    axis = np.empty((3, 3))  # columns: the shape's axes in the object frame
    centre = np.empty(3)
    grad_axis = np.empty((3, 3))
    for b in range(batch):
        nx, ny, nz = normal[b, 0], normal[b, 1], normal[b, 2]
        for shape in range(shape_link.shape[0]):
            l = shape_link[shape]
            for a in range(3):
                centre[a] = (rotation[b, l, a, 0] * shape_pos[shape, 0] + rotation[b, l, a, 1] * shape_pos[shape, 1]
                             + rotation[b, l, a, 2] * shape_pos[shape, 2] + translation[b, l, a])
                for i in range(3):
                    axis[a, i] = rotation[b, l, a, 0] * shape_rot[shape, 0, i] + rotation[b, l, a, 1] * shape_rot[shape, 1, i] + rotation[b, l, a, 2] * shape_rot[shape, 2, i]
            height = nx * centre[0] + ny * centre[1] + nz * centre[2] + offset[b] - radius[shape]
            for i in range(3):
                height -= half_extent[shape, i] * abs(nx * axis[0, i] + ny * axis[1, i] + nz * axis[2, i])
            if height >= 0.0:
                continue
            energy[b] -= height
            if not want_gradient:
                continue
            for i in range(3):
                along = nx * axis[0, i] + ny * axis[1, i] + nz * axis[2, i]
                sign = 1.0 if along > 0 else (-1.0 if along < 0 else 0.0)
                grad_axis[0, i], grad_axis[1, i], grad_axis[2, i] = half_extent[shape, i] * sign * nx, half_extent[shape, i] * sign * ny, half_extent[shape, i] * sign * nz
            grad_centre = (-nx, -ny, -nz)
            for a in range(3):
                grad_translation[b, l, a] += grad_centre[a]
                for j in range(3):
                    # ∂/∂R[a, j] of aᵢ[a] = Σ_j R[a, j]·Q[j, i] and of c[a] = Σ_j R[a, j]·q[j]
                    grad_rotation[b, l, a, j] += (grad_axis[a, 0] * shape_rot[shape, j, 0] + grad_axis[a, 1] * shape_rot[shape, j, 1]
                                                  + grad_axis[a, 2] * shape_rot[shape, j, 2] + grad_centre[a] * shape_pos[shape, j])
    return energy, grad_rotation, grad_translation


class TableKernel:
    """The hand's shapes (links, offsets, half extents, radii) of one ``HandTableClearance``, compiled."""

    def __init__(self, hand, half_extent, radius) -> None:
        def array(tensor, dtype=np.float64):
            return np.ascontiguousarray(tensor.detach().cpu().numpy(), dtype=dtype)

        self.shapes = (array(hand.shape_link, np.int64), array(hand.shape_rot), array(hand.shape_pos), array(half_extent), array(radius))

    def __call__(self, frames, normal, offset_m):
        """E_table (B,) in metres, differentiable in the frames; ``normal`` (B, 3), ``offset_m`` (B,)."""
        energy, grad_rotation, grad_translation = _table_depth(
            *frame_arrays(frames), np.ascontiguousarray(normal.detach().numpy(), dtype=np.float64),
            np.ascontiguousarray(offset_m.detach().numpy(), dtype=np.float64), wants_gradient(frames), *self.shapes,
        )
        return attach(frames, energy, grad_rotation, grad_translation)
