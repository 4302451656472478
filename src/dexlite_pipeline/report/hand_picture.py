"""A picture of what a hand description holds: collision surfaces, contact candidates, palm frame (``dexlite hand-check --picture``).

Drawn with plain matplotlib (Agg, no display or GL): the hand at its pre-grasp pose, in its palm
frame (z the approach direction, x along the fingers; metres), from two sides. Grey dots are
the collision shapes' surface samples, red dots the contact candidates with their normals as
short red strokes, the blue arrow the approach direction from the palm frame's origin. It is
for a person checking a new hand: contacts on the pads, the arrow out of the palm.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dexlite_pipeline.hand.description import HandDescription

VIEWS_DEG = ((20.0, -60.0), (10.0, 30.0))  # (elevation, azimuth) of the two views
MAX_SURFACE_DOTS = 6000
NORMAL_STROKE_M = 0.008


def posed_in_palm_frame(description: HandDescription) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Surface samples (S, 3), contact candidates (C, 3) and their normals (C, 3) at the pre-grasp, in the palm frame (m)."""
    import mujoco

    model = description.mj_model()
    data = mujoco.MjData(model)
    data.qpos[model.jnt_qposadr] = description.pregrasp
    mujoco.mj_kinematics(model, data)
    rot = data.xmat[1:].reshape(-1, 3, 3)
    pos = data.xpos[1:]
    palm = description.palm_frame
    to_palm_rot = palm[:3, :3].T @ rot[0].T  # world -> palm frame
    index = {name: i for i, name in enumerate(description.links)}

    def to_palm(points: np.ndarray, link: np.ndarray) -> np.ndarray:
        world = np.einsum("pij,pj->pi", rot[link], points) + pos[link]
        return (world - pos[0]) @ to_palm_rot.T - palm[:3, :3].T @ palm[:3, 3]

    surface = np.concatenate([to_palm(s.points, np.full(len(s.points), index[s.link])) for s in description.shapes])
    contacts = to_palm(description.contact_points, description.contact_link)
    normals = np.einsum("pij,pj->pi", rot[description.contact_link], description.contact_normals) @ to_palm_rot.T
    return surface, contacts, normals, np.array([0.0, 0.0, 1.0])


def hand_picture_png(description: HandDescription, out: str | Path, size_px: int = 400) -> None:
    """Write the two-view picture of the description to ``out`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    surface, contacts, normals, approach = posed_in_palm_frame(description)
    if len(surface) > MAX_SURFACE_DOTS:
        surface = surface[np.linspace(0, len(surface) - 1, MAX_SURFACE_DOTS).astype(int)]
    low, high = surface.min(axis=0), surface.max(axis=0)
    centre, half = (low + high) / 2, float((high - low).max()) / 2
    arrow = 0.6 * half
    fig = plt.figure(figsize=(2 * size_px / 100, size_px / 100), dpi=100)
    for k, (elev, azim) in enumerate(VIEWS_DEG):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        ax.scatter(*surface.T, s=0.3, c="0.55", depthshade=False)
        ax.scatter(*contacts.T, s=4, c="red", depthshade=False)
        for p, n in zip(contacts, normals):
            ax.plot(*np.stack([p, p + NORMAL_STROKE_M * n]).T, color="red", linewidth=0.5)
        ax.quiver(0, 0, 0, *(arrow * approach), color="blue", linewidth=1.5)
        ax.set_xlim(centre[0] - half, centre[0] + half)
        ax.set_ylim(centre[1] - half, centre[1] + half)
        ax.set_zlim(centre[2] - half, centre[2] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=elev, azim=azim)
        ax.set_xlabel("x (fingers)", fontsize=6)
        ax.set_ylabel("y", fontsize=6)
        ax.set_zlabel("z (approach)", fontsize=6)
        ax.tick_params(labelsize=5)
    fig.suptitle(f"{description.name}: collision surface (grey), {len(contacts)} contact candidates (red), approach (blue)", fontsize=8)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)


__all__ = ["hand_picture_png", "posed_in_palm_frame"]
