"""Checking a hand description against MuJoCo, and the report ``dexlite hand-check`` prints.

``kinematics_errors`` runs the description's pytorch-kinematics chain (float64) and MuJoCo's
``mj_kinematics`` on the same compiled file over joint vectors, and returns the largest
disagreement of any body's world position (m) and orientation (rad), and of any collision
shape's centre placed by the chain's link frames (m). A hand passes when they are within
``POSITION_TOL_M`` and ``ROTATION_TOL_RAD``.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from dexlite_pipeline.hand.derive import quat_to_matrix
from dexlite_pipeline.hand.description import HandDescription

POSITION_TOL_M = 1e-5
ROTATION_TOL_RAD = 1e-4


@dataclass(frozen=True)
class KinematicsErrors:
    """Largest chain-vs-MuJoCo errors over ``vectors`` joint vectors: body position (m), body or geom rotation (rad), geom centre (m)."""

    position_m: float
    rotation_rad: float
    geom_m: float
    vectors: int

    @property
    def ok(self) -> bool:
        return max(self.position_m, self.geom_m) <= POSITION_TOL_M and self.rotation_rad <= ROTATION_TOL_RAD


def rotation_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Angle (rad) of the rotation taking matrix a to matrix b (3, 3), accurate for small angles."""
    diff = a.T @ b
    skew = np.array([diff[2, 1] - diff[1, 2], diff[0, 2] - diff[2, 0], diff[1, 0] - diff[0, 1]])
    return float(np.arctan2(np.linalg.norm(skew) / 2, (np.trace(diff) - 1) / 2))


def random_joint_vectors(description: HandDescription, count: int, seed: int = 0) -> np.ndarray:
    """(count, J) joint vectors uniform within the joints' limits (rad), seeded."""
    limits = description.joint_limits
    return np.random.default_rng(seed).uniform(limits[:, 0], limits[:, 1], size=(count, len(limits)))


def kinematics_errors(description: HandDescription, joints: np.ndarray, mujoco_joints: np.ndarray | None = None) -> KinematicsErrors:
    """The chain at ``joints`` (N, J) against MuJoCo at ``mujoco_joints`` (the same unless given), rad, qpos order."""
    import mujoco
    import torch

    model = description.mj_model()
    data = mujoco.MjData(model)
    chain = description.chain(dtype=torch.float64)
    columns = [description.joint_names.index(name) for name in chain.get_joint_parameter_names()]
    frames = chain.forward_kinematics(torch.as_tensor(joints[:, columns]))
    matrices = {link: frames[link].get_matrix().numpy() for link in description.links}
    mujoco_joints = joints if mujoco_joints is None else mujoco_joints
    position = rotation = geom = 0.0
    for k in range(len(joints)):
        data.qpos[model.jnt_qposadr] = mujoco_joints[k]
        mujoco.mj_kinematics(model, data)
        for b, link in enumerate(description.links):
            matrix = matrices[link][k]
            position = max(position, float(np.linalg.norm(matrix[:3, 3] - data.xpos[b + 1])))
            rotation = max(rotation, rotation_angle(matrix[:3, :3], data.xmat[b + 1].reshape(3, 3)))
        for shape in description.shapes:
            matrix = matrices[shape.link][k]
            centre = matrix[:3, :3] @ np.asarray(shape.pos) + matrix[:3, 3]
            geom = max(geom, float(np.linalg.norm(centre - data.geom_xpos[shape.geom])))
            placed = matrix[:3, :3] @ quat_to_matrix(shape.quat)
            rotation = max(rotation, rotation_angle(placed, data.geom_xmat[shape.geom].reshape(3, 3)))
    return KinematicsErrors(position, rotation, geom, len(joints))


def _vector(values) -> str:
    return "(" + ", ".join(f"{v:+.3f}" for v in values) + ")"


def report_lines(description: HandDescription, errors: KinematicsErrors) -> list[str]:
    """What ``dexlite hand-check`` prints: the derived pieces of the description, one topic a paragraph."""
    root = description.links[0]
    lines = [f"hand {description.name}: {description.source}",
             f"links: {len(description.links)}, rooted at {root}; fingers: {len(description.fingers)} (tips: "
             f"{', '.join(f[-1] for f in description.fingers)}); opposing the others: {', '.join(description.opposing) or 'none'}",
             f"joints: {len(description.joints)} hinges in qpos order, limits in rad, position gain kp in N·m/rad:"]  # fmt: skip
    width = max(len(j.name) for j in description.joints)
    for joint in description.joints:
        drive = f"actuator {joint.actuator}" + (f", kp {joint.kp:g}" if joint.kp is not None else "") if joint.actuator else "no actuator"
        lines.append(f"  {joint.name:<{width}}  [{joint.lower:+.3f}, {joint.upper:+.3f}]  on {joint.link}; {drive}")
    kinds = Counter(shape.kind for shape in description.shapes)
    lines.append(f"collision shapes: {len(description.shapes)} ({', '.join(f'{n} {k}' for k, n in sorted(kinds.items()))}), "
                 f"{sum(len(s.points) for s in description.shapes)} surface samples")  # fmt: skip
    if description.left_out_geoms:
        lines.append(f"  left out (colliding, but in a group with the visual geoms): {', '.join(description.left_out_geoms)}")
    per_link = Counter(shape.link for shape in description.shapes)
    lines.append("  per link: " + ", ".join(f"{link} {n}" for link, n in per_link.items()))
    counts = description.candidates_per_link()
    lines.append(f"contact candidates: {len(description.contact_points)} on {len(counts)} links: "
                 + ", ".join(f"{link} {n}" for link, n in counts.items()))  # fmt: skip
    frame = description.palm_frame
    lines.append(f"palm frame in {root}'s frame: origin {_vector(frame[:3, 3])} m, approach (z) {_vector(frame[:3, 2])}, "
                 f"fingers along (x) {_vector(frame[:3, 0])}")  # fmt: skip
    lines.append("pre-grasp (rad): " + " ".join(f"{v:+.3f}" for v in description.pregrasp))
    verdict = "ok" if errors.ok else "FAILED"
    lines.append(f"FK vs MuJoCo over {errors.vectors} random joint vectors: bodies {errors.position_m:.1e} m, {errors.rotation_rad:.1e} rad, "
                 f"collision shapes {errors.geom_m:.1e} m (limits {POSITION_TOL_M:g} m, {ROTATION_TOL_RAD:g} rad): {verdict}")  # fmt: skip
    return lines


__all__ = ["POSITION_TOL_M", "ROTATION_TOL_RAD", "KinematicsErrors", "kinematics_errors", "random_joint_vectors", "report_lines", "rotation_angle"]
