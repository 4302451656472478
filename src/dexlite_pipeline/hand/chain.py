"""A pytorch-kinematics chain of any hand, built from its compiled MuJoCo model.

pytorch-kinematics 0.10's own MJCF loader cannot read a model under mujoco 4 (its joint-type
table is keyed by enum members, so every joint is a ``KeyError``), so the chain is assembled
from ``pk.Frame``, ``pk.Link`` and ``pk.Joint`` objects: one frame per body below the world,
named after the body, whose joint offset is the body's position (m) and orientation in its
parent, and whose joint is the body's hinge (axis in the body frame, range in rad) or fixed
for a body without a joint. The root body keeps its offset in the world, so the chain's
frames are the bodies' world poses that MuJoCo's ``mj_kinematics`` computes on the same file
(``tests/hand/test_description_fk.py``).

Only what a hand needs is accepted: one tree hanging from the world, hinge joints anchored
at their body's origin, at most one joint per body. Anything else raises ``ChainError``
with a one-line reason rather than being silently mis-modelled.
"""

from __future__ import annotations

import numpy as np
import torch


class ChainError(ValueError):
    """A model whose kinematic tree this chain cannot represent (the message is one line)."""


def body_names(model) -> tuple[str, ...]:
    """The name of every body below the world, in MuJoCo's order; an unnamed body is ``body<id>``."""
    return tuple(model.body(b).name or f"body{b}" for b in range(1, model.nbody))


def check_tree(model) -> None:
    """Raise ``ChainError`` unless the model is one tree of hinge joints at their bodies' origins."""
    import mujoco

    roots = [b for b in range(1, model.nbody) if model.body_parentid[b] == 0]
    if len(roots) != 1:
        raise ChainError(f"the hand must be one body tree under the world; the world holds {len(roots)} bodies")
    if model.njnt == 0:
        raise ChainError("the model has no joints")
    kinds = {int(t) for t in model.jnt_type}
    if kinds != {int(mujoco.mjtJoint.mjJNT_HINGE)}:
        names = sorted(mujoco.mjtJoint(k).name.removeprefix("mjJNT_").lower() for k in kinds - {int(mujoco.mjtJoint.mjJNT_HINGE)})
        raise ChainError(f"only hinge joints are supported, the model has {', '.join(names)} joints")
    if np.abs(model.jnt_pos).max() > 0:
        raise ChainError("a joint is anchored off its body's origin (joint pos), which is not supported")
    if np.any(model.body_jntnum > 1):
        raise ChainError("a body has more than one joint, which is not supported")
    if len(set(body_names(model))) != model.nbody - 1:
        raise ChainError("two bodies share a name")


def pk_chain_from_model(model, *, dtype: torch.dtype = torch.float64, device="cpu", root_offset: bool = True):
    """The model's body tree as a ``pk.Chain`` (frames named after the bodies, joints after the joints).

    root_offset: keep the root body's pose in the world as its frame offset (so the frames are
    world poses); False places the root body at the origin (frames relative to the root body).
    Returns the chain's root ``pk.Frame`` wrapped in a ``pk.Chain``.
    """
    import pytorch_kinematics as pk

    return pk.Chain(root_frame(model, dtype=dtype, device=device, root_offset=root_offset), dtype=dtype, device=device)


def root_frame(model, *, dtype: torch.dtype = torch.float64, device="cpu", root_offset: bool = True):
    """The root ``pk.Frame`` of the model's body tree, its children attached (see ``pk_chain_from_model``)."""
    import pytorch_kinematics as pk

    check_tree(model)
    names = body_names(model)

    def as_t(values) -> torch.Tensor:
        return torch.as_tensor(np.asarray(values, dtype=np.float64), dtype=dtype, device=device)

    def joint_of(body: int) -> pk.Joint:
        is_root = model.body_parentid[body] == 0
        pos = model.body_pos[body] if root_offset or not is_root else np.zeros(3)
        quat = model.body_quat[body] if root_offset or not is_root else np.array([1.0, 0.0, 0.0, 0.0])
        offset = pk.Transform3d(rot=as_t(quat), pos=as_t(pos), dtype=dtype, device=device)
        if model.body_jntnum[body] == 0:
            return pk.Joint(f"{names[body - 1]}:fixed", offset=offset, joint_type="fixed", dtype=dtype, device=device)
        j = int(model.body_jntadr[body])
        return pk.Joint(model.joint(j).name, offset=offset, joint_type="revolute", axis=as_t(model.jnt_axis[j]),
                        limits=tuple(float(v) for v in model.jnt_range[j]), dtype=dtype, device=device)

    frames = {}
    for body in range(1, model.nbody):  # MuJoCo lists every parent before its children
        frames[body] = pk.Frame(names[body - 1], link=pk.Link(names[body - 1]), joint=joint_of(body))
        parent = int(model.body_parentid[body])
        if parent > 0:
            frames[parent].add_child(frames[body])
    return frames[1]


__all__ = ["ChainError", "body_names", "check_tree", "pk_chain_from_model", "root_frame"]
