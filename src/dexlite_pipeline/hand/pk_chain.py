"""The palm-rooted Shadow Hand as a pytorch-kinematics chain, built from the compiled MjModel.

pytorch-kinematics is an independent implementation of batched tree kinematics; the tests
use it as a reference for ``ShadowHand`` (``tests/hand/test_pk_reference.py``) and
``benchmarks/timing/bench_kinematics.py`` times the two against each other. Its own MJCF loader
cannot read the hand under mujoco 4 (its joint-type table is keyed by enum members, so
every joint is a ``KeyError``), so the chain is assembled here from ``pk.Frame``,
``pk.Link`` and ``pk.Joint`` objects using the same MjModel that ``ShadowHand`` compiles
from ``hand.mjcf``: one frame per body, named after the body, whose joint offset is the
body's position (m) and orientation in its parent, and whose joint is the body's hinge
(axis in the body frame, range in rad) or fixed for a body without a joint.

Two ways to place the palm (``hand_pose`` = [t (3, m), static-xyz Euler (3, rad), 22
joints (rad)], as in ``hand.model``):

- ``floating_palm=False``: the chain starts at the palm; ``forward_parts`` composes the
  palm rotation and translation onto the chain's link frames with torch operations, so
  gradients reach them through autograd (the path an optimizer with a 6D rotation takes).
- ``floating_palm=True``: six virtual joints above the palm (prismatic x, y, z, then
  revolute z, y, x, which gives R = Rz Ry Rx), so pytorch-kinematics' analytical backward
  gives the gradient for all 28 pose entries.
"""

from __future__ import annotations

import torch

from dexlite_pipeline.hand.chain import root_frame
from dexlite_pipeline.hand.mjcf import hand_mjcf_string
from dexlite_pipeline.hand.model import JOINT_NAMES, JOINTS, HandFrames
from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix

PALM_JOINTS = ("palm:tx", "palm:ty", "palm:tz", "palm:rz", "palm:ry", "palm:rx")
# Columns of hand_pose feeding the virtual palm joints above, in chain order.
PALM_POSE_COLUMNS = (0, 1, 2, 5, 4, 3)
_PALM_JOINT_AXES = ((1, 0, 0), (0, 1, 0), (0, 0, 1), (0, 0, 1), (0, 1, 0), (1, 0, 0))


def build_pk_chain(model=None, *, floating_palm: bool = False, dtype: torch.dtype = torch.float32, device="cpu"):
    """A ``pk.Chain`` of the palm-rooted hand (the MjModel of ``hand.mjcf`` unless ``model`` is given).

    The tree is ``hand.chain.root_frame``'s: only hinge joints anchored at their body's origin
    occur in the hand; anything else is rejected rather than silently mis-modelled.
    """
    import mujoco
    import pytorch_kinematics as pk

    if model is None:
        model = mujoco.MjModel.from_xml_string(hand_mjcf_string())
    root = root_frame(model, dtype=dtype, device=device)
    if floating_palm:
        for name, axis in reversed(list(zip(PALM_JOINTS, _PALM_JOINT_AXES))):
            kind = "prismatic" if name.startswith("palm:t") else "revolute"
            parent = pk.Frame(name, link=pk.Link(name), joint=pk.Joint(name, joint_type=kind, axis=axis, dtype=dtype, device=device))
            parent.add_child(root)
            root = parent
    return pk.Chain(root, dtype=dtype, device=device)


class PkShadowHand:
    """Link frames of the hand from a pytorch-kinematics chain, in ``ShadowHand``'s link order.

    ``forward`` and ``forward_parts`` take and return what ``ShadowHand``'s methods of the
    same names do (object-frame rotations (B, L, 3, 3) and translations (B, L, 3) in m).
    """

    def __init__(self, device="cpu", dtype: torch.dtype = torch.float32, floating_palm: bool = False) -> None:
        import mujoco

        model = mujoco.MjModel.from_xml_string(hand_mjcf_string())
        self.floating_palm = floating_palm
        self.chain = build_pk_chain(model, floating_palm=floating_palm, dtype=dtype, device=device)
        self.link_names = tuple(model.body(b).name for b in range(1, model.nbody))
        self.frame_index = self.chain.get_frame_indices(*self.link_names)
        names = self.chain.get_joint_parameter_names()
        expected = (PALM_JOINTS if floating_palm else ()) + JOINT_NAMES
        # pose columns (palm columns, then 6 + joint index) in the chain's joint order
        columns = {n: c for n, c in zip(PALM_JOINTS, PALM_POSE_COLUMNS)} | {n: 6 + i for i, n in enumerate(JOINT_NAMES)}
        if sorted(names) != sorted(expected):
            raise RuntimeError(f"unexpected joints in the pytorch-kinematics chain: {names}")
        self.pose_columns = torch.tensor([columns[n] for n in names], device=device)

    def _frames(self, th: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        matrices = self.chain.forward_kinematics_tensor(th).index_select(0, self.frame_index).transpose(0, 1)  # (B, L, 4, 4)
        return matrices[..., :3, :3], matrices[..., :3, 3]

    def forward(self, hand_pose: torch.Tensor) -> HandFrames:
        """All link frames in the object frame for a (B, 28) batch of hand poses."""
        if self.floating_palm:
            return HandFrames(*self._frames(hand_pose.index_select(1, self.pose_columns)))
        return self.forward_parts(euler_xyz_to_matrix(hand_pose[..., 3:6]), hand_pose[..., :3], hand_pose[..., JOINTS])

    def forward_parts(self, palm_rot: torch.Tensor, palm_t: torch.Tensor, joints: torch.Tensor) -> HandFrames:
        """Like ``forward`` with the palm rotation given as a (B, 3, 3) matrix (palm-rooted chain only)."""
        if self.floating_palm:
            raise ValueError("forward_parts needs the palm-rooted chain (floating_palm=False)")
        rot, t = self._frames(joints.index_select(1, self.pose_columns - 6))
        palm_rot = palm_rot[:, None]
        return HandFrames(palm_rot @ rot, palm_t[:, None] + (palm_rot @ t[..., None])[..., 0])


__all__ = ["PALM_JOINTS", "PkShadowHand", "build_pk_chain"]
