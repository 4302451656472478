"""The grasp's associated point: where on the object the local feature is read.

Dex1B: the object point nearest the ray from the palm centre toward the midpoint of
the thumb tip and the middle fingertip, i.e. roughly the point the grasp closes on,
taken on the side of the object the hand is on (``nearest_to_ray``).
For a known grasp (training, dataset expansion) it is computed from the hand's forward
kinematics. A hand from its MJCF (``hand.described.DescribedHand``) has no thumb or middle finger by name: its ray
runs from its palm frame's origin (the centroid of the palm's contact candidates) toward the midpoint of its opposing
fingers' tips (the thumb) and its other fingers' tips, a finger's tip being the mean of the contact candidates on its
last link that has any (the mean of all the tips when no finger opposes); for pure synthesis there is no grasp yet, so ``random_points`` picks a
uniformly random point of the object's cloud (documented rule, seeded): the decoder
then proposes a grasp closing on that point.
"""

from __future__ import annotations

import torch

from dexlite_pipeline.hand.described import is_described
from dexlite_pipeline.hand.model import ShadowHand


def described_tip_points(hand) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """A described hand's fingertip points (F, 3) in their links' frames, their links (F,) and which fingers oppose (F,)."""
    points, links, opposing = [], [], []
    opposing_leaves = set(hand.description.opposing)
    for finger, leaf in zip(hand.finger_links, (names[-1] for names in hand.description.fingers)):
        tip_link = next((link for link in reversed(finger) if bool((hand.contact_link == link).any())), finger[-1])
        on_link = hand.contact_link == tip_link
        points.append(hand.contact_points_local[on_link].mean(dim=0) if bool(on_link.any()) else hand.contact_points_local.new_zeros(3))
        links.append(tip_link)
        opposing.append(leaf in opposing_leaves)
    return torch.stack(points), torch.tensor(links, device=hand.device), torch.tensor(opposing, device=hand.device)


def described_grasp_rays(hand, hand_pose: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``grasp_rays`` of a hand from its MJCF (module docstring): from the palm frame's origin toward the fingertips' midpoint."""
    frames = hand.forward(hand_pose)
    palm_origin = torch.as_tensor(hand.palm_frame_local[:3, 3], dtype=hand_pose.dtype, device=hand_pose.device)
    origin = frames.transform(palm_origin[None], torch.zeros(1, dtype=torch.long, device=hand_pose.device))[:, 0]
    points, links, opposing = described_tip_points(hand)
    tips = frames.transform(points.to(hand_pose.dtype), links)  # (B, F, 3)
    if bool(opposing.any()) and not bool(opposing.all()):
        target = (tips[:, opposing].mean(dim=1) + tips[:, ~opposing].mean(dim=1)) / 2
    else:
        target = tips.mean(dim=1)
    return origin, torch.nn.functional.normalize(target - origin, dim=-1)


def grasp_rays(hand: ShadowHand, hand_pose: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Ray origin (B, 3) at the palm box centre and unit direction (B, 3) toward the mid-fingertip point, for stored
    poses (B, 6 + J) of ``hand`` (the Shadow Hand's thumb and middle finger; a described hand's: ``described_grasp_rays``)."""
    if is_described(hand):
        return described_grasp_rays(hand, hand_pose)
    frames = hand.forward(hand_pose)
    rot, centre = hand.shape_frames(frames)
    palm_shape = int(hand.box_ids[0])
    tips = []
    for link in ("robot0:thdistal", "robot0:mfdistal"):
        s = int(torch.nonzero(hand.shape_link == hand.link_index[link]).flatten()[0])
        reach = hand.shape_size[s, 0] + hand.shape_size[s, 1]
        tips.append(centre[:, s] + rot[:, s, :, 2] * reach)
    origin = centre[:, palm_shape]
    direction = torch.nn.functional.normalize((tips[0] + tips[1]) / 2 - origin, dim=-1)
    return origin, direction


def nearest_to_ray(points: torch.Tensor, origin: torch.Tensor, direction: torch.Tensor) -> torch.Tensor:
    """Index (B,) of the associated point in clouds (B, N, 6: position, outward normal): where the ray meets the object.

    The ray origin + s * direction (s >= 0) passes through the object, so points of its
    near side and of its far side both lie close to it; the nearest one alone is either,
    about half the time the far one (measured on lift-validated training grasps). The far
    side's surface frame faces away from the hand, so the same kind of grasp would be
    anchored in two mirrored frames and the palm pose could not be learned. Only points
    whose outward normal faces back along the ray (the side the hand is on) count; the
    nearest of them is chosen, or the nearest of all points where none faces the ray.
    """
    if points.shape[-1] < 6:
        raise ValueError(f"associated points need clouds with normals, (B, N, 6), got {tuple(points.shape)}")
    rel = points[..., :3] - origin[:, None, :]
    along = (rel * direction[:, None, :]).sum(-1).clamp(min=0.0)
    off_ray = (rel - along[..., None] * direction[:, None, :]).norm(dim=-1)
    facing = (points[..., 3:6] * direction[:, None, :]).sum(-1) < 0.0
    facing = facing | ~facing.any(dim=1, keepdim=True)
    return off_ray.masked_fill(~facing, float("inf")).argmin(dim=1)


def random_points(count: int, points_per_cloud: int, generator: torch.Generator) -> torch.Tensor:
    """Associated points for pure synthesis: uniform random indices into each cloud."""
    return torch.randint(points_per_cloud, (count,), generator=generator)
