"""Bars and a hand-constructed grasp that encloses them, shared by the lift tests.

A round and a square bar lie along the object's x axis (16 cm long, 4 cm thick at the
test scale; the mesh is its own convex piece, SDF at low resolution). The good grasp is
constructed by hand: the palm above the bar, palmar side down, fingers across it, each
finger flexed (one angle shared by its three joints) as far as it stays 0.5 mm clear of
the bar, the thumb folded across the palm. The fingers then hook round the bar: it is
enclosed from above and below, as a bag handle in a hooked hand.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from dexlite_pipeline.hand import JOINT_NAMES
from dexlite_pipeline.hand.rotation import matrix_to_euler_xyz
from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.objects.assets import SdfBank
from dexlite_pipeline.sim.squeeze import object_signed_distance

BAR_IDS = ("round_bar", "square_bar")
SCALE = 0.08  # bars 16 cm long, 4 cm thick
BAR_HALF_THICKNESS_M = 0.02
PALM_HALF_THICKNESS_M = 0.0111  # C_palm0 box, palm frame y
JOINT = {name.split(":")[1]: i for i, name in enumerate(JOINT_NAMES)}
# Palm frame in the object frame: palm x along the bar, palmar side (-y) facing down (-z), fingers along -y.
PALM_ROTATION = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def write_bars(root) -> None:
    """A round and a square bar, 2 x 0.5 (x 0.5) normalized units along x, as prepared assets under ``root``."""
    import trimesh

    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    settings = AssetBuildSettings(sdf_resolution=40, surface_points=1024)
    along_x = trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0])
    round_bar = trimesh.creation.cylinder(radius=0.25, height=2.0, sections=48)
    round_bar.apply_transform(along_x)
    square_bar = trimesh.creation.box(extents=[2.0, 0.5, 0.5])
    for object_id, mesh in (("round_bar", round_bar), ("square_bar", square_bar)):
        write_asset(mesh, object_id, root, settings, {"source": "test"}, convex_pieces=[mesh])


def _pose(bar_in_palm_m, joints) -> torch.Tensor:
    """hand_pose with the bar's centre at ``bar_in_palm_m`` in the palm frame."""
    translation = -(PALM_ROTATION @ torch.as_tensor(bar_in_palm_m, dtype=torch.float32))
    euler = matrix_to_euler_xyz(PALM_ROTATION[None])[0]
    return torch.cat([translation, euler, torch.as_tensor(joints, dtype=torch.float32)])


def _finger_depth_m(hand, bank, poses: torch.Tensor, finger: str) -> torch.Tensor:
    """(B,) deepest point of the finger's links inside the bar (negative: clearance)."""
    depth = object_signed_distance(bank, hand.surface_points(hand.forward(poses)), torch.full((poses.shape[0],), SCALE))
    links = [i for i, name in enumerate(hand.link_names) if name.split(":")[1].startswith(finger)]
    return depth[:, torch.isin(hand.surface_link, torch.tensor(links))].amax(dim=1)


def hook_grasp(hand, asset, clearance_m: float = 0.0005) -> np.ndarray:
    """The constructed grasp: each finger flexed (J2 = J1 = J0) as far as it stays ``clearance_m`` from the bar."""
    bank = SdfBank([asset])
    bar_in_palm = [0.0, -(PALM_HALF_THICKNESS_M + BAR_HALF_THICKNESS_M + 0.002), 0.075]
    joints = np.zeros(22)
    joints[JOINT["THJ3"]] = 1.222  # thumb folded across the palm, clear of the bar
    flex = torch.linspace(0.0, 1.571, 315)  # 5 mrad steps
    for finger in ("FF", "MF", "RF", "LF"):
        ids = [JOINT[f"{finger}J2"], JOINT[f"{finger}J1"], JOINT[f"{finger}J0"]]
        trials = np.repeat(joints[None], len(flex), axis=0)
        trials[:, ids] = flex[:, None].numpy()
        poses = torch.stack([_pose(bar_in_palm, trial) for trial in trials])
        touching = (_finger_depth_m(hand, bank, poses, finger.lower()) >= -clearance_m).nonzero()
        joints[ids] = float(flex[max(int(touching[0]) - 1, 0)]) if len(touching) else 1.571
    return _pose(bar_in_palm, joints).numpy()


def grasp_set(poses, object_ids) -> GraspSet:
    """A grasp set of ``poses`` at the bars' scale."""
    poses = np.asarray(poses, dtype=np.float32).reshape(-1, 28)
    return GraspSet({"hand_pose": poses, "object_id": np.asarray(object_ids, dtype=object), "scale": np.full(len(poses), SCALE, np.float32)})
