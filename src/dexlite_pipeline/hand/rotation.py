"""Rotation conversions used by the hand pose (batched, differentiable torch).

The stored pose uses static-axis x-y-z Euler angles (R = Rz @ Ry @ Rx), exactly as
DexGraspNet's ``WRJR*``; optimizers work in the continuous 6D form (first two columns
of R), which has no wrap-around or gimbal lock.
"""

from __future__ import annotations

import torch


def euler_xyz_to_matrix(euler_rad: torch.Tensor) -> torch.Tensor:
    """(..., 3) static-axis xyz Euler angles -> (..., 3, 3) rotation R = Rz Ry Rx."""
    rx, ry, rz = euler_rad.unbind(-1)
    cx, sx = torch.cos(rx), torch.sin(rx)
    cy, sy = torch.cos(ry), torch.sin(ry)
    cz, sz = torch.cos(rz), torch.sin(rz)
    rows = [
        cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx,
        sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx,
        -sy, cy * sx, cy * cx,
    ]
    return torch.stack(rows, dim=-1).reshape(*euler_rad.shape[:-1], 3, 3)


def matrix_to_euler_xyz(rotation: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) rotation -> (..., 3) static-axis xyz Euler angles (inverse of the above).

    Uses atan2 throughout, so angles come back in (-pi, pi] for x and z and
    [-pi/2, pi/2] for y; at gimbal lock (|cos y| ~ 0) x is set to 0.
    """
    r20 = rotation[..., 2, 0].clamp(-1.0, 1.0)
    ry = torch.asin(-r20)
    cy = torch.sqrt(rotation[..., 0, 0] ** 2 + rotation[..., 1, 0] ** 2)
    regular = cy > 1e-6
    rx = torch.where(regular, torch.atan2(rotation[..., 2, 1], rotation[..., 2, 2]), torch.zeros_like(ry))
    rz_regular = torch.atan2(rotation[..., 1, 0], rotation[..., 0, 0])
    rz_locked = torch.atan2(-rotation[..., 0, 1], rotation[..., 1, 1])
    rz = torch.where(regular, rz_regular, rz_locked)
    return torch.stack([rx, ry, rz], dim=-1)


def matrix_to_rot6d(rotation: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) -> (..., 6): the first two columns, concatenated."""
    return torch.cat([rotation[..., :, 0], rotation[..., :, 1]], dim=-1)


def rot6d_to_matrix(rot6d: torch.Tensor) -> torch.Tensor:
    """(..., 6) -> (..., 3, 3) by Gram-Schmidt (Zhou et al. 2019)."""
    a1, a2 = rot6d[..., :3], rot6d[..., 3:]
    b1 = torch.nn.functional.normalize(a1, dim=-1)
    b2 = torch.nn.functional.normalize(a2 - (b1 * a2).sum(-1, keepdim=True) * b1, dim=-1)
    b3 = torch.cross(b1, b2, dim=-1)
    return torch.stack([b1, b2, b3], dim=-1)


def axis_angle_to_matrix(axis: torch.Tensor, angle_rad: torch.Tensor) -> torch.Tensor:
    """Rodrigues: unit axis (..., 3) and angle (...) -> (..., 3, 3)."""
    x, y, z = axis.unbind(-1)
    c, s = torch.cos(angle_rad), torch.sin(angle_rad)
    one_c = 1.0 - c
    rows = [
        c + x * x * one_c, x * y * one_c - z * s, x * z * one_c + y * s,
        y * x * one_c + z * s, c + y * y * one_c, y * z * one_c - x * s,
        z * x * one_c - y * s, z * y * one_c + x * s, c + z * z * one_c,
    ]
    return torch.stack(rows, dim=-1).reshape(*angle_rad.shape, 3, 3)


def quat_wxyz_to_matrix(quat: torch.Tensor) -> torch.Tensor:
    """(..., 4) unit quaternion (w, x, y, z), MuJoCo's order -> (..., 3, 3)."""
    q = torch.nn.functional.normalize(quat, dim=-1)
    w, x, y, z = q.unbind(-1)
    rows = [
        1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
        2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
        2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y),
    ]
    return torch.stack(rows, dim=-1).reshape(*quat.shape[:-1], 3, 3)

