"""The compiled forward kinematics (``hand.kinematics_kernel``) against the torch version, forward and backward."""

from __future__ import annotations

import torch

from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix


def _inputs(hand, count: int, seed: int):
    g = torch.Generator().manual_seed(seed)
    palm_rot = euler_xyz_to_matrix(torch.pi * (2 * torch.rand(count, 3, generator=g) - 1))
    palm_t = 0.1 * torch.randn(count, 3, generator=g)
    low, high = hand.joint_limits[:, 0], hand.joint_limits[:, 1]
    joints = low + (high - low) * torch.rand(count, 22, generator=g) + 0.2 * torch.randn(count, 22, generator=g)  # a little past the limits too
    return palm_rot, palm_t, joints


def test_frames_and_gradients_equal_the_torch_version(hand):
    palm_rot, palm_t, joints = _inputs(hand, 64, seed=0)
    g = torch.Generator().manual_seed(1)
    weight_r = torch.randn(64, len(hand.link_names), 3, 3, generator=g)
    weight_t = torch.randn(64, len(hand.link_names), 3, generator=g)
    results = []
    for forward in (hand.forward_parts, hand.forward_parts_torch):
        inputs = [x.clone().requires_grad_(True) for x in (palm_rot, palm_t, joints)]
        frames = forward(*inputs)
        loss = (frames.rotation * weight_r).sum() + (frames.translation * weight_t).sum()  # every frame entry matters
        results.append((frames.rotation.detach(), frames.translation.detach(), *torch.autograd.grad(loss, inputs)))
    for name, got, want in zip(("rotation", "translation", "d/d palm rotation", "d/d palm translation", "d/d joints"), *results):
        assert torch.allclose(got, want, rtol=1e-5, atol=1e-5 * float(want.abs().max())), name


def test_only_rotations_or_only_translations_used(hand):
    """Backward with one of the two outputs unused (its gradient None) equals torch's."""
    palm_rot, palm_t, joints = _inputs(hand, 8, seed=2)
    for pick in (0, 1):
        grads = []
        for forward in (hand.forward_parts, hand.forward_parts_torch):
            x = joints.clone().requires_grad_(True)
            frames = forward(palm_rot, palm_t, x)
            output = (frames.rotation, frames.translation)[pick]
            weight = torch.randn(output.shape, generator=torch.Generator().manual_seed(4))
            (grad,) = torch.autograd.grad((output * weight).sum(), x)
            grads.append(grad)
        assert grads[1].abs().max() > 0.1
        assert torch.allclose(grads[0], grads[1], rtol=1e-5, atol=1e-5 * float(grads[1].abs().max()))


def test_a_grasp_gets_the_same_frames_alone_and_in_a_batch(hand):
    palm_rot, palm_t, joints = _inputs(hand, 16, seed=3)
    batch = hand.forward_parts(palm_rot, palm_t, joints)
    for row in (0, 9, 15):
        alone = hand.forward_parts(palm_rot[row : row + 1], palm_t[row : row + 1], joints[row : row + 1])
        assert torch.equal(alone.rotation[0], batch.rotation[row]) and torch.equal(alone.translation[0], batch.translation[row])
