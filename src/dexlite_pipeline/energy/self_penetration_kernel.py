"""E_spen of a batch in one compiled CPU pass (numba), with its gradient in the link frames.

E_spen = Σ over keypoint pairs on different, non-adjacent links of max(0, margin − ‖p − q‖)
(``terms.SelfPenetrationTerm``). Per grasp: every keypoint from its link frame, every listed
pair's distance, and for the pairs closer than the margin their share and its gradient,
−(p − q)/‖p − q‖ for p and the opposite for q, carried to each point's link frame
(dR += g ⊗ x_local, dt += g). The torch version stays the reference and runs on GPUs.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from dexlite_pipeline.energy.frame_gradient import attach, frame_arrays, wants_gradient

_SQRT_EPS = 1e-18  # the torch version's guard inside the square root


@numba.njit(cache=True, nogil=True)
def _self_penetration(rotation, translation, want_gradient, local, link, first, second, margin):
    batch, links = rotation.shape[0], rotation.shape[1]
    count = local.shape[0]
    energy = np.zeros(batch)
    grad_rotation = np.zeros((batch if want_gradient else 0, links, 3, 3))
    grad_translation = np.zeros((batch if want_gradient else 0, links, 3))
    point = np.empty((count, 3))
    gradient = np.empty((count, 3))
    for b in range(batch):
        for k in range(count):
            l = link[k]
            for a in range(3):
                point[k, a] = (rotation[b, l, a, 0] * local[k, 0] + rotation[b, l, a, 1] * local[k, 1] + rotation[b, l, a, 2] * local[k, 2]
                               + translation[b, l, a])
        gradient[:] = 0.0
        total = 0.0
        for pair in range(first.shape[0]):
            i, j = first[pair], second[pair]
            dx, dy, dz = point[i, 0] - point[j, 0], point[i, 1] - point[j, 1], point[i, 2] - point[j, 2]
            distance = math.sqrt(dx * dx + dy * dy + dz * dz + _SQRT_EPS)
            if distance < margin:
                total += margin - distance
                gradient[i, 0] -= dx / distance
                gradient[i, 1] -= dy / distance
                gradient[i, 2] -= dz / distance
                gradient[j, 0] += dx / distance
                gradient[j, 1] += dy / distance
                gradient[j, 2] += dz / distance
        energy[b] = total
        if want_gradient:
            for k in range(count):
                l = link[k]
                for a in range(3):
                    grad_translation[b, l, a] += gradient[k, a]
                    for c in range(3):
                        grad_rotation[b, l, a, c] += gradient[k, a] * local[k, c]
    return energy, grad_rotation, grad_translation


class SelfPenetrationKernel:
    """The keypoints (link-frame positions and links) and the pairs of one ``SelfPenetrationTerm``, compiled."""

    def __init__(self, keypoints_local, keypoint_link, first, second, margin_m: float) -> None:
        self.arrays = (
            np.ascontiguousarray(keypoints_local.detach().cpu().double().numpy()),
            np.ascontiguousarray(keypoint_link.detach().cpu().numpy(), dtype=np.int64),
            np.ascontiguousarray(first.detach().cpu().numpy(), dtype=np.int64),
            np.ascontiguousarray(second.detach().cpu().numpy(), dtype=np.int64),
            float(margin_m),
        )

    def __call__(self, frames):
        """E_spen (B,) in metres, differentiable in the frames."""
        energy, grad_rotation, grad_translation = _self_penetration(*frame_arrays(frames), wants_gradient(frames), *self.arrays)
        return attach(frames, energy, grad_rotation, grad_translation)
