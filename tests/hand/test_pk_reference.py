"""ShadowHand kinematics against pytorch-kinematics, an independent implementation of the same chain."""

import numpy as np
import pytest
import torch
from hand_poses import random_poses

from dexlite_pipeline.hand import JOINT_NAMES, ShadowHand
from dexlite_pipeline.hand.pk_chain import PALM_JOINTS, PkShadowHand, build_pk_chain


def _random_poses(hand, count, seed, dtype=torch.float32):
    return torch.tensor(random_poses(hand, count, seed), dtype=dtype)


@pytest.fixture(scope="module", params=[False, True], ids=["palm-rooted", "floating-palm"])
def pk_hand(request):
    return PkShadowHand(floating_palm=request.param)


def test_chain_has_the_hand_joints_and_limits(hand):
    chain = build_pk_chain()
    assert sorted(chain.get_joint_parameter_names()) == sorted(JOINT_NAMES)
    limits = dict(zip(chain.get_joint_parameter_names(), zip(*chain.get_joint_limits())))
    for name, (low, high) in zip(JOINT_NAMES, hand.joint_limits.tolist()):
        assert limits[name] == pytest.approx((low, high))
    floating = build_pk_chain(floating_palm=True)
    assert floating.get_joint_parameter_names()[:6] == list(PALM_JOINTS)


def test_link_frames_match_pytorch_kinematics(hand, pk_hand):
    assert pk_hand.link_names == hand.link_names
    poses = _random_poses(hand, 64, seed=3)
    ours, reference = hand.forward(poses), pk_hand.forward(poses)
    np.testing.assert_allclose(ours.translation.numpy(), reference.translation.numpy(), atol=1e-5)
    np.testing.assert_allclose(ours.rotation.numpy(), reference.rotation.numpy(), atol=1e-5)

    # Not a trivial agreement: the frames are proper rotations, and the fingertips move by
    # centimetres between configurations, also relative to the palm.
    rot = reference.rotation
    np.testing.assert_allclose((rot @ rot.transpose(-1, -2)).numpy(), np.broadcast_to(np.eye(3), rot.shape), atol=1e-5)
    tip = hand.link_index["robot0:ffdistal"]
    palm = hand.link_index["robot0:palm"]
    local_tip = (reference.rotation[:, palm].transpose(-1, -2) @ (reference.translation[:, tip] - reference.translation[:, palm])[..., None])[..., 0]
    assert (local_tip - local_tip.mean(0)).norm(dim=-1).max() > 0.01
    assert reference.translation.std(dim=0).min() > 0.05


def test_gradients_match_pytorch_kinematics(pk_hand):
    """The gradient w.r.t. all 28 pose entries (joint angles and palm pose), in float64."""
    hand64 = ShadowHand(dtype=torch.float64)
    pk64 = PkShadowHand(dtype=torch.float64, floating_palm=pk_hand.floating_palm)
    poses = _random_poses(hand64, 16, seed=4, dtype=torch.float64)
    g = torch.Generator().manual_seed(0)
    w_t = torch.randn(16, 23, 3, generator=g, dtype=torch.float64)
    w_r = torch.randn(16, 23, 3, 3, generator=g, dtype=torch.float64)
    grads = []
    for model in (hand64, pk64):
        x = poses.clone().requires_grad_(True)
        frames = model.forward(x)
        grads.append(torch.autograd.grad((frames.translation * w_t).sum() + (frames.rotation * w_r).sum(), x)[0])
    assert grads[0][:, 6:].abs().min() > 0  # every joint moves some link
    np.testing.assert_allclose(grads[0].numpy(), grads[1].numpy(), atol=1e-10, rtol=1e-8)
