"""A per-grasp energy computed outside autograd, attached to the link frames with its precomputed gradient.

The compiled energy terms (``penetration_kernel``, ``self_penetration_kernel``) compute each grasp's value and
its gradient in the link frames in one pass; ``attach`` makes that value differentiable, so backward is one
multiplication by the upstream gradient.
"""

from __future__ import annotations

import numpy as np
import torch


class _AttachGradient(torch.autograd.Function):
    @staticmethod
    def forward(ctx, rotation, translation, value, grad_rotation, grad_translation):
        ctx.save_for_backward(grad_rotation, grad_translation)
        return value

    @staticmethod
    def backward(ctx, grad_value):
        grad_rotation, grad_translation = ctx.saved_tensors
        return grad_value[:, None, None, None] * grad_rotation, grad_value[:, None, None] * grad_translation, None, None, None


def wants_gradient(frames) -> bool:
    """Whether a value computed from ``frames`` needs its gradient (autograd on and the frames differentiable)."""
    return torch.is_grad_enabled() and (frames.rotation.requires_grad or frames.translation.requires_grad)


def attach(frames, value: np.ndarray, grad_rotation: np.ndarray, grad_translation: np.ndarray) -> torch.Tensor:
    """``value`` (B,) as a tensor of the frames' dtype, differentiable in ``frames`` with the given gradients
    (B, L, 3, 3) and (B, L, 3) when ``wants_gradient(frames)``."""
    dtype = frames.rotation.dtype
    out = torch.from_numpy(value).to(dtype)
    if not wants_gradient(frames):
        return out
    return _AttachGradient.apply(
        frames.rotation, frames.translation, out, torch.from_numpy(grad_rotation).to(dtype), torch.from_numpy(grad_translation).to(dtype)
    )


def frame_arrays(frames) -> tuple[np.ndarray, np.ndarray]:
    """The link rotations (B, L, 3, 3) and translations (B, L, 3) as contiguous float64 arrays."""
    return (np.ascontiguousarray(frames.rotation.detach().numpy(), dtype=np.float64),
            np.ascontiguousarray(frames.translation.detach().numpy(), dtype=np.float64))
