"""What a hand description derives from the MJCF beyond its geoms: fingers, pad sides, contact candidates, palm frame, pre-grasp.

All of it is read off the kinematic tree at the zero joint vector (MuJoCo's ``mj_kinematics`` on
the compiled model) and the collision shapes' surface samples; nothing is specific to one hand:

- **Fingers**: every path from a child of the root body to a leaf body that passes a joint.
  A finger's *contact links* are its last ``CONTACT_SEGMENTS`` (3) jointed bodies and the fixed
  bodies below them (e.g. Allegro's ``ff_tip``, which holds the fingertip capsule): the proximal,
  middle and distal phalanges, where the Shadow Hand's hand-written candidates lie too (a power
  grasp wraps the proximal phalanges around the object).
- **Pad side** of a contact link: the side its finger curls toward. A hinge of unit axis ``a``
  turning by +q moves a point at ``e`` from the joint by ``a × e``; the finger flexes toward
  the joint's larger-magnitude limit (sign ``s``), so the pad faces ``s · (a × e)``, ``e`` the
  centroid of the link's collision surface seen from the joint. A joint whose range is
  symmetric says nothing about flexion; such a link takes the pad side of the nearest link
  below it in the finger.
- **Contact candidates**: surface samples of a contact link's collision shapes whose normal
  is within ``PAD_CONE_DEG`` of its pad side and which lie on no other shape of the same link
  (a face buried in a neighbouring box is no pad), thinned to ``per_link`` points by farthest-
  point sampling; on the palm, likewise around the palm normal.
- **Palm normal** (the approach direction): the mean pad side of the fingers' contact links,
  in the root body's frame, one vote per finger, over the largest group of fingers that agree
  (a thumb opposes the others and is outvoted). **Palm frame**: origin at the centroid of the
  palm's candidates (of the root's shapes when it has none), z the palm normal, x the voting
  fingers' mean direction (finger base to tip, made orthogonal to z), y = z × x.
- **Pre-grasp**: the open hand, every joint at 0 rad clipped into its range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

PAD_CONE_DEG = 35.0  # a sample is on the pad when its normal is within this angle of the pad side
BURIED_M = 5e-4  # a sample deeper than this inside another shape of its link is buried, not pad
# A sample is recessed, not pad, when its link's surface rises more than RECESSED_M in front of it (along its normal)
# within RECESS_RADIUS_M of its normal line: an object touches it only with that surface RECESSED_M deep inside, deeper
# than the lift test's start cap (2 mm); a convex object of radius 3 cm curves away by only 0.6 mm over 6 mm.
RECESSED_M = 0.002
RECESS_RADIUS_M = 0.006


@dataclass(frozen=True)
class LinkSurface:
    """The collision surface samples of one link, in its frame (m): points (P, 3), normals (P, 3), shape of each (P,)."""

    points: np.ndarray
    normals: np.ndarray
    shape: np.ndarray


def quat_to_matrix(quat) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion (w, x, y, z), MuJoCo's order."""
    w, x, y, z = (float(v) for v in np.asarray(quat, dtype=np.float64) / np.linalg.norm(quat))
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])  # fmt: skip


def zero_pose_frames(model) -> tuple[np.ndarray, np.ndarray]:
    """World rotation (L, 3, 3) and position (L, 3) of every body below the world at the zero joint vector."""
    import mujoco

    data = mujoco.MjData(model)
    data.qpos[:] = 0.0
    mujoco.mj_kinematics(model, data)
    return data.xmat[1:].reshape(-1, 3, 3).copy(), data.xpos[1:].copy()


def fingers(parents: tuple[int, ...], jointed: tuple[bool, ...]) -> tuple[tuple[int, ...], ...]:
    """Link paths (indices) from a child of the root to each leaf, for the leaves that a joint moves."""
    children = {i: [] for i in range(len(parents))}
    for i, p in enumerate(parents):
        if p >= 0:
            children[p].append(i)
    paths = []
    for leaf in (i for i in range(len(parents)) if not children[i] and parents[i] >= 0):
        path = [leaf]
        while parents[path[-1]] > 0:
            path.append(parents[path[-1]])
        path.reverse()
        if any(jointed[i] for i in path):
            paths.append(tuple(path))
    return tuple(paths)


# Jointed links of a finger, counted from its tip, that carry contact candidates. 3: the Shadow Hand's own four fingers'
# candidate links (proximal, middle, distal); with 2 (no proximal phalanx) Allegro passed the energy thresholds 57 and
# held 66 of 192 grasps on twelve household objects, with 3: 73 and 70 (LEAP: 10 and 35, 16 and 35).
CONTACT_SEGMENTS = 3


def contact_links_of(path: tuple[int, ...], jointed: tuple[bool, ...], segments: int = CONTACT_SEGMENTS) -> tuple[int, ...]:
    """A finger's last ``segments`` jointed links and the fixed links below them."""
    jointed_on_path = [i for i in path if jointed[i]]
    first = path.index(jointed_on_path[-min(segments, len(jointed_on_path))])
    return path[first:]


def pad_sides(model, path: tuple[int, ...], links: tuple[int, ...], surfaces: dict[int, LinkSurface]) -> dict[int, np.ndarray]:
    """Pad side (unit vector in the link's frame) of each of a finger's contact links that has one (see the module doc)."""
    rot, pos = zero_pose_frames(model)
    sides: dict[int, np.ndarray] = {}
    for link in links:
        joint_link = next((i for i in reversed(path[: path.index(link) + 1]) if model.body_jntnum[i + 1] > 0), None)
        if joint_link is None or link not in surfaces:
            continue
        j = int(model.body_jntadr[joint_link + 1])
        low, high = model.jnt_range[j]
        if abs(low + high) <= 0.1 * (high - low):
            continue  # symmetric range: no flexion direction
        sign = 1.0 if abs(high) >= abs(low) else -1.0
        to_link = rot[link].T @ rot[joint_link]  # joint-link frame -> this link's frame
        axis = to_link @ model.jnt_axis[j]
        anchor = rot[link].T @ (pos[joint_link] - pos[link])
        lever = surfaces[link].points.mean(axis=0) - anchor
        side = sign * np.cross(axis, lever)
        if np.linalg.norm(side) > 1e-9:
            sides[link] = side / np.linalg.norm(side)
    for link in reversed(links):  # symmetric joints: take the side of the nearest link below
        if link not in sides and link in surfaces:
            below = [i for i in links[links.index(link) + 1 :] if i in sides]
            if below:
                sides[link] = rot[link].T @ rot[below[0]] @ sides[below[0]]
    return sides


def farthest_points(points: np.ndarray, count: int, first: int) -> np.ndarray:
    """Indices of ``count`` points spread by farthest-point sampling, starting from index ``first``."""
    chosen = [first]
    distance = np.linalg.norm(points - points[first], axis=1)
    while len(chosen) < min(count, len(points)):
        nxt = int(np.argmax(distance))
        chosen.append(nxt)
        distance = np.minimum(distance, np.linalg.norm(points - points[nxt], axis=1))
    return np.asarray(chosen)


def recessed(points: np.ndarray, normals: np.ndarray, surface: np.ndarray) -> np.ndarray:
    """(P,) bool: which samples (points, outward normals (P, 3)) have a point of ``surface`` (the link's samples, (S, 3))
    more than ``RECESSED_M`` in front of them within ``RECESS_RADIUS_M`` of their normal line (m, link frame)."""
    out = np.zeros(len(points), dtype=bool)
    for start in range(0, len(points), 256):
        rel = surface[None] - points[start : start + 256, None]  # (p, S, 3)
        ahead = np.einsum("psk,pk->ps", rel, normals[start : start + 256])
        lateral = np.linalg.norm(rel - ahead[..., None] * normals[start : start + 256, None], axis=-1)
        out[start : start + 256] = ((ahead > RECESSED_M) & (lateral < RECESS_RADIUS_M)).any(axis=1)
    return out


def facing(surface: LinkSurface, side: np.ndarray, buried, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Up to ``count`` samples of a link facing ``side`` (within the pad cone), not buried and not recessed; (points, normals).

    buried(points, shape ids) -> bool mask: the samples inside another shape of the same link. Recessed (``recessed``):
    behind another surface of the link, e.g. a face in the gap between two boxes, which no object reaches. When every
    facing sample is recessed the recessed ones are kept (a link's pad is then its least recessed face).
    """
    keep = surface.normals @ side >= math.cos(math.radians(PAD_CONE_DEG))
    keep &= ~buried(surface.points, surface.shape)
    hidden = np.zeros(len(keep), dtype=bool)
    hidden[keep] = recessed(surface.points[keep], surface.normals[keep], surface.points)
    if (keep & ~hidden).any():
        keep &= ~hidden
    points, normals = surface.points[keep], surface.normals[keep]
    if len(points) == 0:
        return points, normals
    chosen = farthest_points(points, count, first=int(np.argmax(points @ side)))
    return points[chosen], normals[chosen]


AGREE_DEG = 45.0  # fingers whose pad sides are this close agree on the palm normal


def palm_normal(model, finger_sides: list[dict[int, np.ndarray]]) -> tuple[np.ndarray, tuple[int, ...]]:
    """The palm normal in the root body's frame and the fingers that voted for it (indices into ``finger_sides``).

    Each finger votes with the mean pad side of its contact links. The votes of the largest
    group of fingers that agree within ``AGREE_DEG`` are averaged; the others (a thumb, which
    opposes the fingers and faces them rather than the palm's side) do not count.
    """
    rot, _ = zero_pose_frames(model)
    votes: dict[int, np.ndarray] = {}
    for f, sides in enumerate(finger_sides):
        if sides:
            mean = np.mean([rot[0].T @ rot[link] @ side for link, side in sides.items()], axis=0)
            if np.linalg.norm(mean) > 1e-9:
                votes[f] = mean / np.linalg.norm(mean)
    if not votes:
        raise ValueError("no finger has a pad side (no joint with a flexion direction under a collision shape)")
    cosine = math.cos(math.radians(AGREE_DEG))
    agree = {f: tuple(g for g in votes if votes[f] @ votes[g] >= cosine) for f in votes}
    voters = max(agree.values(), key=len)
    normal = np.mean([votes[f] for f in voters], axis=0)
    if np.linalg.norm(normal) < 1e-6:
        raise ValueError("the fingers' pad sides cancel out: no palm normal")
    return normal / np.linalg.norm(normal), voters


def palm_frame(model, paths: tuple[tuple[int, ...], ...], normal: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """Palm frame (4, 4) in the root body's frame: z the palm normal, x along ``paths`` (finger base to tip), at ``origin``."""
    rot, pos = zero_pose_frames(model)
    along = np.mean([rot[0].T @ (pos[path[-1]] - pos[path[0]]) for path in paths], axis=0)
    along = along - (along @ normal) * normal
    if np.linalg.norm(along) < 1e-6:  # fingers along the normal: any x orthogonal to z
        along = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    x = along / np.linalg.norm(along)
    frame = np.eye(4)
    frame[:3, 0], frame[:3, 1], frame[:3, 2], frame[:3, 3] = x, np.cross(normal, x), normal, origin
    return frame


def open_pregrasp(limits: np.ndarray) -> np.ndarray:
    """The open pre-grasp joint vector (rad): 0 clipped into each joint's [lower, upper]."""
    return np.clip(np.zeros(len(limits)), limits[:, 0], limits[:, 1])


__all__ = ["CONTACT_SEGMENTS", "LinkSurface", "contact_links_of", "facing", "farthest_points", "fingers", "open_pregrasp", "pad_sides",
           "recessed",
           "palm_frame", "palm_normal", "quat_to_matrix", "zero_pose_frames"]
