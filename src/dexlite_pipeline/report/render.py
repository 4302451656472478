"""Headless pictures of grasps: hand and object together, drawn with plain matplotlib.

Runs on any CPU machine without a display or GL library (matplotlib's Agg backend).
The Shadow Hand is the gym model's own visual meshes (read from the compiled MjModel, so no
STL parsing here), each placed by ``ShadowHand.forward``; a hand from its MJCF (``DescribedHand``)
is its collision shapes (those its energies and ``dexlite hand-check`` use: primitives as
triangle meshes, mesh geoms as the file's meshes), placed by its own ``forward``. The hand
of a grasp store is the one its attributes record (``hand_of_store``). The object is its normalized
mesh times the grasp's scale. Both go into ONE Poly3DCollection, so matplotlib's
painter's sort orders hand and object faces together; faces are shaded by a fixed
headlight (Lambert) so shape reads without a GL renderer.
"""

from __future__ import annotations

import functools
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from dexlite_pipeline.hand.model import POSE_DIM, ShadowHand, mujoco_geom
from dexlite_pipeline.io.grasp_store import DEFAULT_GRASP_TYPE, GRASP_TYPE
from dexlite_pipeline.objects.assets import find_asset_dir

HAND_RGB = (0.85, 0.55, 0.35)
OBJECT_RGB = (0.35, 0.55, 0.85)
TABLE_RGBA = (0.45, 0.42, 0.38, 0.35)  # the table of tabletop mode: a translucent square under the object
DEFAULT_VIEWS_DEG = ((25.0, -60.0), (-20.0, 120.0))  # (elevation, azimuth) pairs, roughly opposite sides
VISUAL_GROUP = 1  # the gym hand's visual geoms (collision geoms are group 4)


class RenderError(ValueError):
    """A grasp that cannot be rendered (bad index, missing mesh)."""


@dataclass(frozen=True)
class HandVisual:
    """The hand's visual meshes in their link frames: vertices (V, 3), faces (F, 3), link of each vertex (V,)."""

    vertices: np.ndarray
    faces: np.ndarray
    vertex_link: np.ndarray


@functools.cache
def hand_visual() -> HandVisual:
    """Visual mesh and box geoms of the palm-rooted hand, in the frame of the link that carries them."""
    import mujoco
    import trimesh

    from dexlite_pipeline.hand.mjcf import hand_mjcf_string
    from dexlite_pipeline.hand.rotation import quat_wxyz_to_matrix

    model = mujoco.MjModel.from_xml_string(hand_mjcf_string())
    vertices, faces, links = [], [], []
    offset = 0
    for g in range(model.ngeom):
        if int(model.geom_group[g]) != VISUAL_GROUP:
            continue
        kind = int(model.geom_type[g])
        if kind == int(mujoco_geom("mesh")):
            mesh_id = int(model.geom_dataid[g])
            v0, nv = int(model.mesh_vertadr[mesh_id]), int(model.mesh_vertnum[mesh_id])
            f0, nf = int(model.mesh_faceadr[mesh_id]), int(model.mesh_facenum[mesh_id])
            local_v = np.asarray(model.mesh_vert[v0 : v0 + nv], dtype=np.float64)
            local_f = np.asarray(model.mesh_face[f0 : f0 + nf], dtype=np.int64)
        elif kind == int(mujoco_geom("box")):
            box = trimesh.creation.box(extents=2 * np.asarray(model.geom_size[g]))
            local_v, local_f = np.asarray(box.vertices), np.asarray(box.faces)
        else:
            continue
        rot = quat_wxyz_to_matrix(torch.as_tensor(model.geom_quat[g], dtype=torch.float64)).numpy()
        vertices.append(local_v @ rot.T + model.geom_pos[g])
        faces.append(local_f + offset)
        links.append(np.full(len(local_v), int(model.geom_bodyid[g]) - 1))
        offset += len(local_v)
    return HandVisual(np.concatenate(vertices), np.concatenate(faces), np.concatenate(links))


def _primitive_mesh(kind: str, size) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (m) and faces of a MuJoCo primitive geom of ``kind`` and ``size`` (``geom_size``) in the geom's frame."""
    import trimesh

    r, h = float(size[0]), float(size[1])
    if kind == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=r)
    elif kind == "capsule":  # radius, half length of the segment along z
        mesh = trimesh.creation.capsule(height=2 * h, radius=r, count=[12, 12])
    elif kind == "cylinder":
        mesh = trimesh.creation.cylinder(radius=r, height=2 * h, sections=16)
    elif kind == "ellipsoid":
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
        mesh.vertices = mesh.vertices * np.asarray(size, dtype=np.float64)[:3]
    elif kind == "box":
        mesh = trimesh.creation.box(extents=2 * np.asarray(size, dtype=np.float64)[:3])
    else:
        raise RenderError(f"cannot draw a collision shape of kind {kind}")
    return np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)


def described_hand_visual(description) -> HandVisual:
    """The collision shapes of a hand from its MJCF (``HandDescription.shapes``) as triangle meshes in their links'
    frames (m): a primitive drawn as itself, a mesh geom as the file's mesh; each vertex's link indexes
    ``description.links``, the order of the hand's ``forward`` frames."""
    model = None
    index = {name: i for i, name in enumerate(description.links)}
    vertices, faces, links = [], [], []
    offset = 0
    for shape in description.shapes:
        if shape.kind == "mesh":
            model = description.mj_model() if model is None else model
            mesh_id = int(model.geom_dataid[shape.geom])
            v0, nv = int(model.mesh_vertadr[mesh_id]), int(model.mesh_vertnum[mesh_id])
            f0, nf = int(model.mesh_faceadr[mesh_id]), int(model.mesh_facenum[mesh_id])
            local_v = np.asarray(model.mesh_vert[v0 : v0 + nv], dtype=np.float64)
            local_f = np.asarray(model.mesh_face[f0 : f0 + nf], dtype=np.int64)
        else:
            local_v, local_f = _primitive_mesh(shape.kind, shape.size)
        from dexlite_pipeline.hand.rotation import quat_wxyz_to_matrix

        rot = quat_wxyz_to_matrix(torch.as_tensor(shape.quat, dtype=torch.float64)).numpy()
        vertices.append(local_v @ rot.T + np.asarray(shape.pos, dtype=np.float64))
        faces.append(local_f + offset)
        links.append(np.full(len(local_v), index[shape.link]))
        offset += len(local_v)
    if not vertices:
        raise RenderError(f"hand {description.name}: no collision shape to draw")
    return HandVisual(np.concatenate(vertices), np.concatenate(faces), np.concatenate(links))


def visual_of(hand) -> HandVisual:
    """What is drawn of ``hand``: the Shadow Hand's visual meshes (``hand_visual``), or a described hand's collision shapes
    (``described_hand_visual``, built once per hand object)."""
    description = getattr(hand, "description", None)
    if description is None:
        return hand_visual()
    cached = getattr(hand, "_report_visual", None)
    if cached is None:
        cached = described_hand_visual(description)
        hand._report_visual = cached
    return cached


def hand_of_store(attrs: dict, device="cpu"):
    """The hand model a grasp store's poses are of (attribute ``hand``; none: the Shadow Hand), for drawing them.

    A hand named by a file must still be that file (its SHA-256 recorded) and joints: ``RenderError`` in one line otherwise."""
    from dexlite_pipeline.hand.choice import hand_record, resolve_hand
    from dexlite_pipeline.io.grasp_store import DEFAULT_HAND, hand_identity, hand_joint_names, store_hand

    name = store_hand(attrs)
    if name == DEFAULT_HAND:
        return ShadowHand(device=device)
    try:
        record = hand_record(name)
    except ValueError as exc:
        raise RenderError(f"the grasps' hand {name} cannot be made: {exc}") from exc
    if hand_identity(record) != hand_identity(attrs) or list(record["joint_names"]) != list(hand_joint_names(attrs)):
        raise RenderError(f"the grasps' hand {name} is not the hand that file describes now (its contents or joints changed)")
    return resolve_hand(name, device)


def hand_mesh_world(hand: ShadowHand, hand_pose: np.ndarray, visual: HandVisual | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The hand's mesh (vertices in metres in the object frame, faces) for one pose (28 numbers for the Shadow Hand,
    6 + J for a described hand: ``hand.pose_dim``).

    ``visual`` replaces the hand's full mesh (``visual_of``; e.g. a decimated copy for the interactive view).
    """
    pose = np.asarray(hand_pose, dtype=np.float64).reshape(-1)
    width = int(getattr(hand, "pose_dim", POSE_DIM))
    if pose.shape != (width,) or not np.isfinite(pose).all():
        raise RenderError(f"hand_pose must be {width} finite numbers, got shape {pose.shape}")
    visual = visual_of(hand) if visual is None else visual
    with torch.no_grad():
        frames = hand.forward(torch.as_tensor(pose[None], dtype=hand.dtype, device=hand.device))
        rot = frames.rotation[0].double().cpu().numpy()[visual.vertex_link]  # (V, 3, 3)
        trans = frames.translation[0].double().cpu().numpy()[visual.vertex_link]
    world = np.einsum("vij,vj->vi", rot, visual.vertices) + trans
    return world, visual.faces


def object_mesh_world(objects_dirs, object_id: str, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """The object's mesh in metres (normalized mesh x scale), vertices and faces."""
    import trimesh

    mesh_path = find_asset_dir(objects_dirs, object_id) / "mesh.obj"
    if not mesh_path.is_file():
        raise RenderError(f"{mesh_path}: object mesh not found")
    mesh = trimesh.load(mesh_path, force="mesh", process=False)
    return np.asarray(mesh.vertices, dtype=np.float64) * float(scale), np.asarray(mesh.faces, dtype=np.int64)


def _shaded_colors(triangles: np.ndarray, rgb: tuple[float, float, float], view_dir: np.ndarray) -> np.ndarray:
    """Per-face RGBA: ambient + Lambert term for a light at the camera (two-sided)."""
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True).clip(min=1e-12)
    lambert = np.abs(normals @ view_dir)
    shade = 0.35 + 0.65 * lambert
    colors = np.empty((len(triangles), 4))
    colors[:, :3] = np.clip(np.asarray(rgb)[None, :] * shade[:, None], 0, 1)
    colors[:, 3] = 1.0
    return colors


def _view_direction(elev_deg: float, azim_deg: float) -> np.ndarray:
    """Unit vector from the scene toward a matplotlib 3D camera."""
    e, a = np.radians(elev_deg), np.radians(azim_deg)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


def table_square(normal, offset_m: float, centre: np.ndarray, half_m: float) -> np.ndarray:
    """(4, 3) corners of a square of side 2·``half_m`` in the table plane n·x + offset = 0 (object frame, m),
    centred under ``centre``."""
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    foot = centre - (n @ centre + offset_m) * n
    u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    return np.stack([foot + half_m * (a * u + b * v) for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))])


def grasp_table(grasps, row: int) -> tuple[np.ndarray, float] | None:
    """The table a grasp store recorded for one row (normal, offset in metres), or None (floating, or none recorded)."""
    if "support_normal" not in grasps.arrays or "support_offset_m" not in grasps.arrays:
        return None
    normal = np.asarray(grasps.arrays["support_normal"][row], dtype=np.float64)
    offset = float(grasps.arrays["support_offset_m"][row])
    return (normal, offset) if np.isfinite(normal).all() and np.isfinite(offset) and np.linalg.norm(normal) > 0 else None


def draw_grasp(
    ax, hand_mesh: tuple[np.ndarray, np.ndarray], object_mesh: tuple[np.ndarray, np.ndarray], elev_deg: float, azim_deg: float,
    table: tuple[np.ndarray, float] | None = None,
) -> None:
    """Draw hand and object into a 3D axes from one viewpoint, equal aspect, axes hidden; with ``table``
    (normal, offset in metres, object frame) a translucent square of the table under the object."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    view = _view_direction(elev_deg, azim_deg)
    hand_tris = hand_mesh[0][hand_mesh[1]]
    object_tris = object_mesh[0][object_mesh[1]]
    triangles = np.concatenate([object_tris, hand_tris])
    colors = np.concatenate([_shaded_colors(object_tris, OBJECT_RGB, view), _shaded_colors(hand_tris, HAND_RGB, view)])
    # Frame the object and the hand; a hand far from the object (>25 cm) is left out of the frame.
    obj_v = object_mesh[0]
    centre = (obj_v.max(0) + obj_v.min(0)) / 2
    radius = float(np.linalg.norm(obj_v - centre, axis=1).max())
    if table is not None:
        square = table_square(table[0], table[1], centre, 1.2 * radius)
        ax.add_collection3d(Poly3DCollection([square], facecolors=[TABLE_RGBA], edgecolors=[TABLE_RGBA[:3]], linewidths=0.5))
    ax.add_collection3d(Poly3DCollection(triangles, facecolors=colors, edgecolors="none", linewidths=0))
    near_hand = hand_mesh[0][np.linalg.norm(hand_mesh[0] - centre, axis=1) < radius + 0.25]
    pts = np.concatenate([obj_v, near_hand])
    lo, hi = pts.min(0), pts.max(0)
    mid, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-3)
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_zlim(mid[2] - half, mid[2] + half)
    ax.set_box_aspect((1, 1, 1), zoom=1.2)
    ax.view_init(elev=elev_deg, azim=azim_deg)
    ax.set_axis_off()


def render_grasp_png(
    hand: ShadowHand,
    hand_pose: np.ndarray,
    object_id: str,
    scale: float,
    objects_dirs,
    out: str | Path | None = None,
    title: str = "",
    views_deg=DEFAULT_VIEWS_DEG,
    size_px: int = 360,
    table: tuple[np.ndarray, float] | None = None,
) -> bytes:
    """Render one grasp from each viewpoint side by side (on its ``table`` in tabletop mode); return PNG bytes
    (and write ``out`` if given)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    hand_mesh = hand_mesh_world(hand, hand_pose)
    object_mesh = object_mesh_world(objects_dirs, object_id, scale)
    dpi = 100
    fig = plt.figure(figsize=(size_px * len(views_deg) / dpi, size_px / dpi), dpi=dpi)
    for k, (elev, azim) in enumerate(views_deg):
        ax = fig.add_subplot(1, len(views_deg), k + 1, projection="3d")
        draw_grasp(ax, hand_mesh, object_mesh, elev, azim, table)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.subplots_adjust(left=0, right=1, bottom=0, top=0.92 if title else 1, wspace=0)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    plt.close(fig)
    data = buffer.getvalue()
    if out is not None:
        from dexlite_pipeline.atomic import atomic_path

        with atomic_path(out) as tmp:
            Path(tmp).write_bytes(data)
    return data


def type_of(arrays, row: int) -> str:
    """The grasp type of row ``row`` of a store's arrays (``grasp_type``; power in a store without it, as
    ``grasp_store.grasp_types`` reads it): the pictures' and the 3-D view's labels name it."""
    return str(arrays[GRASP_TYPE][row]) if GRASP_TYPE in arrays else DEFAULT_GRASP_TYPE


def render_store_row(grasps_path: str, index: int, objects_dirs: list[str], out: str, size_px: int = 400) -> None:
    """Render row ``index`` of the grasp store at ``grasps_path`` (hand and object) to the PNG ``out``.

    Raises ``RenderError`` naming the store and row for an index out of range, a pose that is
    not finite or a scale that is not positive.
    """
    from dexlite_pipeline.io.grasp_store import read_grasp_store

    grasps = read_grasp_store(grasps_path)
    if not 0 <= index < len(grasps):
        raise RenderError(f"{grasps_path}: index {index} out of range (store has {len(grasps)} grasps)")
    object_id, scale = str(grasps.object_id[index]), float(grasps.scale[index])
    bad = [i for i, v in enumerate(np.asarray(grasps.hand_pose[index], dtype=np.float64)) if not np.isfinite(v)]
    if bad:
        raise RenderError(f"{grasps_path}: row {index} ({object_id}): hand_pose is not finite at position(s) {', '.join(map(str, bad))}")
    if not np.isfinite(scale) or scale <= 0:
        raise RenderError(f"{grasps_path}: row {index} ({object_id}): scale {scale} is not a positive number")
    title = f"{object_id}  scale {scale:.3f}  grasp {index}  {type_of(grasps.arrays, index)}"
    if "lift_success" in grasps.arrays:
        title += "  lift " + ("success" if bool(grasps.arrays["lift_success"][index]) else "failure")
    render_grasp_png(hand_of_store(grasps.attrs), grasps.hand_pose[index], object_id, scale, objects_dirs, out=out, title=title, size_px=size_px,
                     table=grasp_table(grasps, index))
