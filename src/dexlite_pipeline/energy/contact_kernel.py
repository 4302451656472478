"""The four contact points of each grasp with their SDF distances and normals, compiled for the CPU (numba).

Feeds E_fc and E_dis (``GraspEnergy.context``) what ``SdfBank.signed_distance`` gives the torch
path: each chosen pad point from its link frame, the grid's trilinear distance (``grid_kernel``) (metres, positive
inside) and the outward normal, the normalized −∇ of the interpolant inside the grid box (or the
direction away from the box outside it). Backward needs the derivatives of both with respect to
the point: the distance's gradient (as in ``penetration_kernel``) and the normal's Jacobian,
(I − n·nᵀ)/‖v‖ · dv/dp, where dv/dp is minus the interpolant's Hessian (trilinear: zero on the
diagonal, bilinear off it) per unclamped axis inside the box and the identity on clamped axes
outside it. They are kept from the forward pass, so backward is a few products per contact.
"""

from __future__ import annotations

import math

import numba
import numpy as np
import torch

from dexlite_pipeline.energy.frame_gradient import frame_arrays
from dexlite_pipeline.energy.grid_kernel import axis_gradient, grid_coordinates, trilinear

_NORMALIZE_EPS = 1e-12  # torch.nn.functional.normalize's floor on the norm


@numba.njit(cache=True, nogil=True)
def _contact_geometry(rotation, translation, contact_index, object_index, scale, local, link, volumes, grid_min, voxel_size):
    batch, contacts = contact_index.shape
    g = volumes.shape[1]
    top = g - 1 - 1e-4
    points = np.empty((batch, contacts, 3))
    distance = np.empty((batch, contacts))
    normal = np.empty((batch, contacts, 3))
    distance_gradient = np.empty((batch, contacts, 3))
    normal_jacobian = np.empty((batch, contacts, 3, 3))
    inward_hessian = np.empty((3, 3))
    direction_jacobian = np.empty((3, 3))
    direction = np.empty(3)
    for b in range(batch):
        o, s = object_index[b], scale[b]
        h = voxel_size[o]
        for k in range(contacts):
            candidate = contact_index[b, k]
            l = link[candidate]
            for a in range(3):
                points[b, k, a] = (rotation[b, l, a, 0] * local[candidate, 0] + rotation[b, l, a, 1] * local[candidate, 1]
                                   + rotation[b, l, a, 2] * local[candidate, 2] + translation[b, l, a])
            ux, uy, uz, ucx, ucy, ucz, outside = grid_coordinates(grid_min, o, h, top, points[b, k, 0] / s, points[b, k, 1] / s, points[b, k, 2] / s)
            value, gx, gy, gz, hxy, hxz, hyz = trilinear(volumes, o, ucx, ucy, ucz)
            distance[b, k] = (value - outside) * s
            u, clamped = (ux, uy, uz), (ucx, ucy, ucz)
            inside_box = (0.0 <= ux <= top, 0.0 <= uy <= top, 0.0 <= uz <= top)
            inward = (gx, gy, gz)
            for a in range(3):
                distance_gradient[b, k, a] = axis_gradient(u[a], clamped[a], top, inward[a], h, outside)
            if outside > 0.0:  # the direction away from the grid box; it moves with the clamped axes only
                for a in range(3):
                    direction[a] = points[b, k, a] / s - (grid_min[o, a] + clamped[a] * h)
                    for c in range(3):
                        direction_jacobian[a, c] = (1.0 / s) if (a == c and not inside_box[a]) else 0.0
            else:  # minus the interpolant's gradient; its Hessian is zero on the diagonal
                inward_hessian[0, 0], inward_hessian[0, 1], inward_hessian[0, 2] = 0.0, hxy, hxz
                inward_hessian[1, 0], inward_hessian[1, 1], inward_hessian[1, 2] = hxy, 0.0, hyz
                inward_hessian[2, 0], inward_hessian[2, 1], inward_hessian[2, 2] = hxz, hyz, 0.0
                for a in range(3):
                    direction[a] = -inward[a]
                    for c in range(3):
                        direction_jacobian[a, c] = -inward_hessian[a, c] / (h * s) if inside_box[c] else 0.0
            norm = math.sqrt(direction[0] ** 2 + direction[1] ** 2 + direction[2] ** 2)
            if norm > _NORMALIZE_EPS:
                for a in range(3):
                    normal[b, k, a] = direction[a] / norm
                for a in range(3):
                    for c in range(3):
                        total = 0.0
                        for m in range(3):
                            projector = ((1.0 if a == m else 0.0) - normal[b, k, a] * normal[b, k, m]) / norm
                            total += projector * direction_jacobian[m, c]
                        normal_jacobian[b, k, a, c] = total
            else:
                for a in range(3):
                    normal[b, k, a] = direction[a] / _NORMALIZE_EPS
                    for c in range(3):
                        normal_jacobian[b, k, a, c] = direction_jacobian[a, c] / _NORMALIZE_EPS
    return points, distance, normal, distance_gradient, normal_jacobian


@numba.njit(cache=True, nogil=True)
def _contact_backward(grad_points, grad_distance, grad_normal, distance_gradient, normal_jacobian, contact_index, local, link, links):
    """Gradients of the link rotations (B, L, 3, 3) and translations (B, L, 3) from those of points, distances, normals."""
    batch, contacts = contact_index.shape
    grad_rotation = np.zeros((batch, links, 3, 3))
    grad_translation = np.zeros((batch, links, 3))
    for b in range(batch):
        for k in range(contacts):
            candidate = contact_index[b, k]
            l = link[candidate]
            for a in range(3):
                total = grad_points[b, k, a] + grad_distance[b, k] * distance_gradient[b, k, a]
                for m in range(3):
                    total += grad_normal[b, k, m] * normal_jacobian[b, k, m, a]
                grad_translation[b, l, a] += total
                for c in range(3):
                    grad_rotation[b, l, a, c] += total * local[candidate, c]
    return grad_rotation, grad_translation


class ContactKernel:
    """The contact candidates (link-frame points and links) and the SDF grids of one ``GraspEnergy``, compiled."""

    def __init__(self, bank, candidates_local: torch.Tensor, candidate_link: torch.Tensor) -> None:
        g = bank.resolution
        self.local = np.ascontiguousarray(candidates_local.detach().cpu().double().numpy())
        self.link = np.ascontiguousarray(candidate_link.detach().cpu().numpy(), dtype=np.int64)
        self.grids = (
            np.ascontiguousarray(bank.volumes.detach().cpu().numpy(), dtype=np.float32).reshape(-1, g, g, g),
            np.ascontiguousarray(bank.grid_min.detach().cpu().double().numpy()),
            np.ascontiguousarray(bank.voxel_size.detach().cpu().double().numpy()),
        )

    def __call__(self, frames, contact_index: torch.Tensor, object_index: torch.Tensor, scale: torch.Tensor):
        """Points (B, C, 3), signed distances (B, C) and outward normals (B, C, 3) of the chosen contacts, differentiable
        in the frames."""
        return _ContactGeometry.apply(frames.rotation, frames.translation, contact_index, object_index, scale, self)


class _ContactGeometry(torch.autograd.Function):
    @staticmethod
    def forward(ctx, rotation, translation, contact_index, object_index, scale, kernel):
        from dexlite_pipeline.hand.model import HandFrames

        index = np.ascontiguousarray(contact_index.numpy(), dtype=np.int64)
        points, distance, normal, distance_gradient, normal_jacobian = _contact_geometry(
            *frame_arrays(HandFrames(rotation, translation)), index, object_index.numpy().astype(np.int64, copy=False),
            scale.detach().numpy().astype(np.float64), kernel.local, kernel.link, *kernel.grids,
        )
        ctx.saved = (distance_gradient, normal_jacobian, index, kernel, rotation.shape[1], rotation.dtype)
        dtype = rotation.dtype
        return tuple(torch.from_numpy(x).to(dtype) for x in (points, distance, normal))

    @staticmethod
    def backward(ctx, grad_points, grad_distance, grad_normal):
        distance_gradient, normal_jacobian, index, kernel, links, dtype = ctx.saved
        batch, contacts = index.shape

        def as_array(grad, shape):
            return np.zeros(shape) if grad is None else np.ascontiguousarray(grad.numpy(), dtype=np.float64)

        grad_rotation, grad_translation = _contact_backward(
            as_array(grad_points, (batch, contacts, 3)), as_array(grad_distance, (batch, contacts)), as_array(grad_normal, (batch, contacts, 3)),
            distance_gradient, normal_jacobian, index, kernel.local, kernel.link, links,
        )
        return torch.from_numpy(grad_rotation).to(dtype), torch.from_numpy(grad_translation).to(dtype), None, None, None, None
