"""The network's pose representation: translation, 6D rotation and joints, free of wrap-around.

A stored pose is 6 + J numbers (the hand's J joints: 22 for the Shadow Hand, 28 numbers in all; 16 for Allegro
and LEAP): palm translation (m), static-xyz Euler angles (rad), joints (rad). The Euler angles' ±pi wrap-around would
turn two nearly identical grasps into a huge reconstruction error (and their gimbal lock makes them a poor regression
target). The networks therefore read and write 9 + J features ``[t / TRANSLATION_UNIT_M (3), rot6d (6), joints (J)]``
(31 for the Shadow Hand, ``pose_feature_dim``); the reconstruction loss compares translations, full rotation matrices
and joints, and poses are converted back to the stored Euler form only at the end. Every function here reads the
joint count from its input's width.
"""

from __future__ import annotations

import math

import torch

from dexlite_pipeline.hand.model import JOINT_NAMES, ROTATION, TRANSLATION
from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix, matrix_to_euler_xyz, matrix_to_rot6d, rot6d_to_matrix

STORED_JOINTS_START = 6  # a stored pose's joints follow the palm translation (3) and Euler angles (3)
FEATURE_JOINTS_START = 9  # the features' joints follow the scaled translation (3) and the 6D rotation (6)
SHADOW_JOINT_COUNT = len(JOINT_NAMES)  # 22: a model file that records no hand is the Shadow Hand's
TRANSLATION_UNIT_M = 0.1  # palm translations are tenths of a metre: this brings them to O(1)


def pose_feature_dim(joint_count: int) -> int:
    """Network features of a pose of a hand with ``joint_count`` joints: 9 + J (31 for the Shadow Hand)."""
    return FEATURE_JOINTS_START + int(joint_count)


POSE_FEATURE_DIM = pose_feature_dim(SHADOW_JOINT_COUNT)  # the Shadow Hand's 31


def pose_to_features(hand_pose: torch.Tensor) -> torch.Tensor:
    """(B, 6 + J) stored poses -> (B, 9 + J) network features."""
    return parts_to_features(euler_xyz_to_matrix(hand_pose[:, ROTATION]), hand_pose[:, TRANSLATION], hand_pose[:, STORED_JOINTS_START:])


def parts_to_features(rotation: torch.Tensor, translation_m: torch.Tensor, joints: torch.Tensor) -> torch.Tensor:
    """Palm rotation (B, 3, 3), translation (B, 3) in metres and joints (B, J) -> (B, 9 + J) features."""
    return torch.cat([translation_m / TRANSLATION_UNIT_M, matrix_to_rot6d(rotation), joints], dim=1)


def rotate_features(features: torch.Tensor, rotation: torch.Tensor) -> torch.Tensor:
    """The same grasps (B, 9 + J) of an object turned by ``rotation`` (B, 3, 3) about its origin."""
    palm_rot, palm_t, joints = features_to_parts(features)
    return parts_to_features(rotation @ palm_rot, (rotation @ palm_t[..., None])[..., 0], joints)


def vertical_rotation(angle_rad: torch.Tensor) -> torch.Tensor:
    """(N, 3, 3) rotations about the object frame's z axis by ``angle_rad`` (N,): the turns an object standing on a
    table (its z axis up, as the pipeline's objects stand) can take without changing how it rests."""
    cos, sin = angle_rad.cos(), angle_rad.sin()
    zero, one = torch.zeros_like(angle_rad), torch.ones_like(angle_rad)
    return torch.stack([cos, -sin, zero, sin, cos, zero, zero, zero, one], dim=1).reshape(-1, 3, 3)


def turned_clouds(clouds: torch.Tensor, angle_rad: torch.Tensor) -> torch.Tensor:
    """Clouds (C, P, 6: points, normals) turned about z by ``angle_rad`` (C,)."""
    turn = vertical_rotation(angle_rad.to(clouds.dtype)).transpose(1, 2)
    return torch.cat([clouds[..., :3] @ turn, clouds[..., 3:] @ turn], dim=2)


def box_centred_clouds(clouds: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Clouds (C, P, 6: points, normals) moved in the table's plane so that their points' bounding box is centred on the
    z axis, and the offsets (C, 3; m, z = 0) taken off (a point p of the moved cloud is p + offset in the cloud's frame).

    A prepared object's origin is its bounding box's centre. A cloud turned about z by an angle that is not a multiple
    of 90 degrees has another bounding box, whose centre is off the axis by up to a quarter of the object's length for
    a long one (about 2 cm for a hammer): moved back, it stands where the same object prepared at that heading would."""
    points = clouds[..., :3]
    offset = (points.amax(dim=1) + points.amin(dim=1)) / 2
    offset = torch.cat([offset[:, :2], torch.zeros_like(offset[:, 2:])], dim=1)
    return torch.cat([points - offset[:, None, :], clouds[..., 3:]], dim=2), offset


def turn_stored_poses(hand_pose: torch.Tensor, angle_rad: torch.Tensor) -> torch.Tensor:
    """The same grasps (N, 6 + J stored poses) of objects turned about their z axis by ``angle_rad`` (N,).

    With R = Rz Ry Rx (static xyz Euler), Rz(a) R only adds a to the z angle, wrapped to (-pi, pi]; the palm
    position turns with the object.
    """
    turned = hand_pose.clone()
    turned[:, TRANSLATION] = (vertical_rotation(angle_rad) @ hand_pose[:, TRANSLATION, None])[..., 0]
    z_angle = hand_pose[:, ROTATION.start + 2] + angle_rad
    turned[:, ROTATION.start + 2] = torch.remainder(z_angle + math.pi, 2 * math.pi) - math.pi
    return turned


def shift_translation(features: torch.Tensor, offset_m: torch.Tensor) -> torch.Tensor:
    """Features (B, 9 + J) with ``offset_m`` (B, 3) added to the palm translation."""
    return torch.cat([features[:, :3] + offset_m / TRANSLATION_UNIT_M, features[:, 3:]], dim=1)


def features_to_parts(features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(B, 9 + J) features -> palm rotation (B, 3, 3), palm translation (B, 3) in metres, joints (B, J)."""
    return rot6d_to_matrix(features[:, 3:9]), features[:, :3] * TRANSLATION_UNIT_M, features[:, FEATURE_JOINTS_START:]


def features_to_pose(features: torch.Tensor) -> torch.Tensor:
    """(B, 9 + J) features -> (B, 6 + J) stored poses (static-xyz Euler)."""
    rotation, translation, joints = features_to_parts(features)
    return torch.cat([translation, matrix_to_euler_xyz(rotation), joints], dim=1)


def reconstruction_error(predicted: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Squared error per grasp (B,), summed over translation (tenths of a metre), rotation matrix and joints.

    Summed, not averaged, over the 12 + J components (34 for the Shadow Hand): the VAE's Gaussian log-likelihood sums
    over dimensions, and a mean would weaken the data term that much against the KL term (the
    latent collapses) and against the energies. Rotations are compared as matrices, so the loss is continuous across
    Euler wrap-around.
    """
    rot_p, t_p, q_p = features_to_parts(predicted)
    rot_t, t_t, q_t = features_to_parts(target)
    squared = torch.cat(
        [((t_p - t_t) / TRANSLATION_UNIT_M) ** 2, (rot_p - rot_t).flatten(1) ** 2, (q_p - q_t) ** 2], dim=1
    )
    return squared.sum(dim=1)


def pose_errors(predicted_pose: torch.Tensor, target_pose: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Per grasp (B,) each: palm rotation error (degrees, geodesic angle), palm translation error (mm) and mean
    absolute joint error (rad) between stored poses (B, 6 + J)."""
    rot_p = euler_xyz_to_matrix(predicted_pose[:, ROTATION])
    rot_t = euler_xyz_to_matrix(target_pose[:, ROTATION])
    cosine = ((rot_p.transpose(1, 2) @ rot_t).diagonal(dim1=1, dim2=2).sum(-1) - 1.0) / 2.0
    angle_deg = torch.rad2deg(torch.arccos(cosine.clamp(-1.0, 1.0)))
    translation_mm = (predicted_pose[:, TRANSLATION] - target_pose[:, TRANSLATION]).norm(dim=-1) * 1000.0
    joint_rad = (predicted_pose[:, STORED_JOINTS_START:] - target_pose[:, STORED_JOINTS_START:]).abs().mean(dim=-1)
    return angle_deg, translation_mm, joint_rad
