"""The hand's forward kinematics and its backward pass, compiled for the CPU (numba).

The torch version (``ShadowHand.forward_parts_torch``) batches a tree level at a time and
costs ~120 small operations forward and as many backward, a fixed ~1 ms per step that
dominated small batches. Here each grasp walks its 23 links in MuJoCo's order (parents
first): R = R_parent·R_offset·R_joint(q), t = t_parent + R_parent·p_offset, with
R_joint(q) = cos q·I + (1 − cos q)·a·aᵀ + sin q·[a]× (Rodrigues, unit axis a). The backward
pass walks the links in reverse, handing each link's gradient to its parent:

    dL/dM = dL/dR · R_jointᵀ,   dL/dq = ⟨Mᵀ·dL/dR, dR_joint/dq⟩,   M = R_parent·R_offset,
    dL/dR_parent += dL/dM · R_offsetᵀ + dL/dt ⊗ p_offset,   dL/dt_parent += dL/dt,

ending in the palm's rotation and translation. Float64 inside; the frames come back in the
caller's dtype. ``tests/hand/test_kinematics_kernel.py`` checks both passes against torch.
"""

from __future__ import annotations

import numba
import numpy as np
import torch


@numba.njit(cache=True, nogil=True, inline="always")
def _joint_rotation(axis, q, out, derivative):
    """Rodrigues rotation (3, 3) about unit ``axis`` by ``q`` into ``out``, and dR/dq into ``derivative``."""
    x, y, z = axis[0], axis[1], axis[2]
    c, s = np.cos(q), np.sin(q)
    one_c = 1.0 - c
    out[0, 0], out[0, 1], out[0, 2] = c + x * x * one_c, x * y * one_c - z * s, x * z * one_c + y * s
    out[1, 0], out[1, 1], out[1, 2] = y * x * one_c + z * s, c + y * y * one_c, y * z * one_c - x * s
    out[2, 0], out[2, 1], out[2, 2] = z * x * one_c - y * s, z * y * one_c + x * s, c + z * z * one_c
    # d/dq: −sin q·I + sin q·a·aᵀ + cos q·[a]×
    derivative[0, 0], derivative[0, 1], derivative[0, 2] = -s + x * x * s, x * y * s - z * c, x * z * s + y * c
    derivative[1, 0], derivative[1, 1], derivative[1, 2] = y * x * s + z * c, -s + y * y * s, y * z * s - x * c
    derivative[2, 0], derivative[2, 1], derivative[2, 2] = z * x * s - y * c, z * y * s + x * c, -s + z * z * s


@numba.njit(cache=True, nogil=True)
def _forward(palm_rot, palm_t, joints, parent, offset_pos, offset_rot, body_joint, joint_axis):
    batch, links = palm_rot.shape[0], parent.shape[0]
    rotation = np.empty((batch, links, 3, 3))
    translation = np.empty((batch, links, 3))
    joint = np.empty((3, 3))
    derivative = np.empty((3, 3))
    middle = np.empty((3, 3))
    for b in range(batch):
        for link in range(links):
            p = parent[link]
            parent_rot = palm_rot[b] if p < 0 else rotation[b, p]
            parent_t = palm_t[b] if p < 0 else translation[b, p]
            for i in range(3):
                translation[b, link, i] = parent_t[i] + (parent_rot[i, 0] * offset_pos[link, 0] + parent_rot[i, 1] * offset_pos[link, 1]
                                                         + parent_rot[i, 2] * offset_pos[link, 2])
                for j in range(3):
                    middle[i, j] = parent_rot[i, 0] * offset_rot[link, 0, j] + parent_rot[i, 1] * offset_rot[link, 1, j] + parent_rot[i, 2] * offset_rot[link, 2, j]
            if body_joint[link] < 0:
                rotation[b, link] = middle
                continue
            _joint_rotation(joint_axis[body_joint[link]], joints[b, body_joint[link]], joint, derivative)
            for i in range(3):
                for j in range(3):
                    rotation[b, link, i, j] = middle[i, 0] * joint[0, j] + middle[i, 1] * joint[1, j] + middle[i, 2] * joint[2, j]
    return rotation, translation


@numba.njit(cache=True, nogil=True)
def _backward(palm_rot, joints, rotation, grad_rotation, grad_translation, parent, offset_pos, offset_rot, body_joint, joint_axis):
    """Gradients of the palm rotation (B, 3, 3), palm translation (B, 3) and joints (B, J) from those of the frames."""
    batch, links = rotation.shape[0], parent.shape[0]
    grad_palm_rot = np.zeros((batch, 3, 3))
    grad_palm_t = np.zeros((batch, 3))
    grad_joints = np.zeros(joints.shape)
    grad_r = np.empty((links, 3, 3))
    grad_t = np.empty((links, 3))
    joint = np.empty((3, 3))
    derivative = np.empty((3, 3))
    middle = np.empty((3, 3))
    grad_middle = np.empty((3, 3))
    for b in range(batch):
        grad_r[:] = grad_rotation[b]
        grad_t[:] = grad_translation[b]
        for link in range(links - 1, -1, -1):
            p = parent[link]
            parent_rot = palm_rot[b] if p < 0 else rotation[b, p]
            if body_joint[link] < 0:
                grad_middle[:] = grad_r[link]
            else:
                _joint_rotation(joint_axis[body_joint[link]], joints[b, body_joint[link]], joint, derivative)
                for i in range(3):
                    for j in range(3):
                        middle[i, j] = (parent_rot[i, 0] * offset_rot[link, 0, j] + parent_rot[i, 1] * offset_rot[link, 1, j]
                                        + parent_rot[i, 2] * offset_rot[link, 2, j])
                        grad_middle[i, j] = grad_r[link, i, 0] * joint[j, 0] + grad_r[link, i, 1] * joint[j, 1] + grad_r[link, i, 2] * joint[j, 2]
                total = 0.0
                for i in range(3):
                    for j in range(3):
                        total += grad_r[link, i, j] * (middle[i, 0] * derivative[0, j] + middle[i, 1] * derivative[1, j] + middle[i, 2] * derivative[2, j])
                grad_joints[b, body_joint[link]] += total
            target_r = grad_palm_rot[b] if p < 0 else grad_r[p]
            target_t = grad_palm_t[b] if p < 0 else grad_t[p]
            for i in range(3):
                target_t[i] += grad_t[link, i]
                for j in range(3):
                    target_r[i, j] += (grad_middle[i, 0] * offset_rot[link, j, 0] + grad_middle[i, 1] * offset_rot[link, j, 1]
                                       + grad_middle[i, 2] * offset_rot[link, j, 2] + grad_t[link, i] * offset_pos[link, j])
    return grad_palm_rot, grad_palm_t, grad_joints


class HandKinematics:
    """The hand's tree as NumPy arrays, and ``forward(palm_rot, palm_t, joints)`` differentiable through torch."""

    def __init__(self, parent, offset_pos: torch.Tensor, offset_rot: torch.Tensor, body_joint, joint_axis: torch.Tensor) -> None:
        as_float = lambda tensor: np.ascontiguousarray(tensor.detach().cpu().double().numpy())  # noqa: E731
        self.tree = (
            np.asarray(parent, dtype=np.int64),
            as_float(offset_pos),
            as_float(offset_rot),
            np.asarray(body_joint, dtype=np.int64),
            as_float(joint_axis),
        )
        if any(p >= link for link, p in enumerate(parent)):
            raise ValueError("the links must come parents first")

    def forward(self, palm_rot: torch.Tensor, palm_t: torch.Tensor, joints: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Link rotations (B, L, 3, 3) and translations (B, L, 3) in ``palm_rot``'s dtype."""
        return _Kinematics.apply(palm_rot, palm_t, joints, self)


def _numpy(tensor: torch.Tensor) -> np.ndarray:
    return np.ascontiguousarray(tensor.detach().numpy(), dtype=np.float64)


class _Kinematics(torch.autograd.Function):
    @staticmethod
    def forward(ctx, palm_rot, palm_t, joints, kinematics):
        arrays = (_numpy(palm_rot), _numpy(palm_t), _numpy(joints))
        rotation, translation = _forward(*arrays, *kinematics.tree)
        ctx.kinematics = kinematics
        ctx.arrays = (arrays[0], arrays[2], rotation)
        ctx.dtypes = (palm_rot.dtype, palm_t.dtype, joints.dtype)
        return torch.from_numpy(rotation).to(palm_rot.dtype), torch.from_numpy(translation).to(palm_rot.dtype)

    @staticmethod
    def backward(ctx, grad_rotation, grad_translation):
        palm_rot, joints, rotation = ctx.arrays
        grad_rotation = np.zeros(rotation.shape) if grad_rotation is None else _numpy(grad_rotation)
        grad_translation = np.zeros(rotation.shape[:-1]) if grad_translation is None else _numpy(grad_translation)
        grads = _backward(palm_rot, joints, rotation, grad_rotation, grad_translation, *ctx.kinematics.tree)
        return (*(torch.from_numpy(g).to(dtype) for g, dtype in zip(grads, ctx.dtypes)), None)
