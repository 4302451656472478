"""Shared geometry of the generated objects (``household`` and the shape families): revolved profiles, vessel walls,
handles, booleans, boxes and rods, and the check that a generated mesh is one closed solid. All lengths in metres.

Moved out of ``household.py`` unchanged, so the original twelve families build bit-identical meshes.
"""

from __future__ import annotations

import math

import numpy as np

# Angular resolution of revolved surfaces: chord error under 0.15 mm at a 10 cm radius.
REVOLVE_SECTIONS = 64
# Profile points closer than this (m) to a neighbour are one point.
MIN_SPACING = 1e-5


class HouseholdMeshError(ValueError):
    """A generated mesh that is not a closed single solid (a bug in a family's parameters)."""


def check_solid(mesh, name: str) -> None:
    """Raise ``HouseholdMeshError`` unless ``mesh`` is one closed, consistently wound body of positive volume."""
    problems = []
    if not mesh.is_watertight:
        problems.append("not watertight")
    if not mesh.is_winding_consistent:
        problems.append("inconsistent winding")
    if mesh.body_count != 1:
        problems.append(f"{mesh.body_count} bodies")
    if not mesh.volume > 0:
        problems.append(f"volume {mesh.volume:.3g}")
    if problems:
        raise HouseholdMeshError(f"{name}: generated mesh is not a single closed solid ({', '.join(problems)})")


def revolve(profile, sections: int = REVOLVE_SECTIONS) -> object:
    """Solid of revolution about z of an (r, z) profile that starts and ends on the axis (outward normals either way),
    ``sections`` segments around (6: a hexagonal prism-like handle)."""
    import trimesh

    profile = np.asarray(profile, dtype=np.float64)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(profile, axis=0), axis=1) > MIN_SPACING])
    mesh = trimesh.creation.revolve(profile[keep], sections=sections)
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def offset_inward(curve: np.ndarray, distance: float) -> np.ndarray:
    """The (r, z) polyline ``curve`` (running upward) offset by ``distance`` toward the axis side, along its normals.

    Vertex normals are the mitred mean of the adjacent segment normals, so a straight wall
    keeps exactly ``distance``; curves here bend far less sharply than the wall is thick.
    """
    tangents = np.diff(curve, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    # Left normal of an upward-running wall profile points toward the axis (-r).
    normals = np.stack([-tangents[:, 1], tangents[:, 0]], axis=1)
    vertex = np.vstack([normals[:1], normals[:-1] + normals[1:], normals[-1:]])
    vertex /= np.linalg.norm(vertex, axis=1, keepdims=True)
    # Mitre: scale by 1 / cos(half the turn) so each segment is offset by exactly ``distance``.
    cosines = np.ones(len(curve))
    cosines[1:-1] = np.clip(np.einsum("ij,ij->i", vertex[1:-1], normals[1:]), 0.5, 1.0)
    return curve + vertex * (distance / cosines)[:, None]


def clip_z(curve: np.ndarray, z_min: float, z_max: float) -> np.ndarray:
    """The part of a polyline (z increasing along it) between two heights, ends interpolated onto them."""
    z = curve[:, 1]
    if z[0] > z_min or z[-1] < z_max:
        raise HouseholdMeshError(f"profile does not span z {z_min:.4f}..{z_max:.4f} m")

    def at(level: float) -> np.ndarray:
        i = int(np.searchsorted(z, level)) - 1
        i = min(max(i, 0), len(z) - 2)
        t = (level - z[i]) / (z[i + 1] - z[i])
        return curve[i] + t * (curve[i + 1] - curve[i])

    # Points within 10 µm of a cut would leave sliver faces that the revolve cannot close.
    inside = curve[(z > z_min + MIN_SPACING) & (z < z_max - MIN_SPACING)]
    return np.vstack([at(z_min), inside, at(z_max)])


def wall_curve(base_radius: float, rim_radius: float, height: float, roundness: float, n: int = 32) -> np.ndarray:
    """Outer wall of a vessel, (r, z) from the base plane up to the rim and 1 cm beyond it.

    ``roundness`` 0: a straight (conical) wall whose foot is rounded over 6 mm, horizontal on the
    base plane; 1: a quarter ellipse (a bowl) from (``base_radius``, 0), horizontal there, to the rim,
    vertical there; in between, the radii of the two blended at the ellipse's heights. The rim
    tangent is continued 1 cm above ``height`` so that offsets and clips at the rim are clean.
    """
    fillet = min(0.006, 0.3 * height)
    slope = (rim_radius - base_radius) / height
    bend = np.linspace(0.0, math.pi / 2, 10)
    foot = np.stack([base_radius - fillet + fillet * np.sin(bend) + slope * fillet * (1 - np.cos(bend)), fillet * (1 - np.cos(bend))], axis=1)
    straight = np.vstack([foot, [[base_radius + slope * height, height]]])
    if roundness > 0:
        phi = np.linspace(0.0, math.pi / 2, n)
        z = height * (1 - np.cos(phi))
        r_ellipse = base_radius + (rim_radius - base_radius) * np.sin(phi)
        r_straight = np.interp(z, straight[:, 1], straight[:, 0])
        curve = np.stack([(1 - roundness) * r_straight + roundness * r_ellipse, z], axis=1)
    else:
        curve = straight
    tangent = curve[-1] - curve[-2]
    tangent /= np.linalg.norm(tangent)
    extension = curve[-1] + tangent * (0.01 / max(tangent[1], 1e-6))
    return np.vstack([curve, extension])


def vessel_curves(height, rim_radius, base_radius, wall, base_thickness, roundness):
    """(outer wall from z = 0 to the rim, inner wall from the cavity floor to 1 cm above the rim), (r, z) polylines."""
    outer = wall_curve(base_radius, rim_radius, height, roundness)
    inner = clip_z(offset_inward(outer, wall), base_thickness, height + 0.01)
    return clip_z(outer, 0.0, height), inner


def open_vessel(height, rim_radius, base_radius, wall, base_thickness, roundness):
    """A cup or bowl: one revolve of its wall section (outer wall up, flat rim, inner wall down, cavity floor)."""
    outer, inner = vessel_curves(height, rim_radius, base_radius, wall, base_thickness, roundness)
    inner = clip_z(inner, base_thickness, height)
    return revolve(np.vstack([[0.0, 0.0], outer, inner[::-1], [0.0, base_thickness]]))


def boolean(kind: str, meshes):
    """Union or difference (first minus the rest) of closed meshes, by manifold3d (exact, keeps them closed)."""
    import trimesh

    operation = {"union": trimesh.boolean.union, "difference": trimesh.boolean.difference}[kind]
    return operation(meshes, engine="manifold")


def handle_torus(attach_radius, centre_z, span, reach, tube_radius):
    """A torus in the xz plane whose centre circle meets the wall (x = ``attach_radius``) at
    ``centre_z`` ± ``span``/2 and reaches ``reach`` beyond it (centre-line)."""
    import trimesh

    half = span / 2
    # circle of radius a centred at x = attach + d: a - d = half^2 / reach, a + d = reach
    major = (reach + half**2 / reach) / 2
    offset = (reach - half**2 / reach) / 2
    torus = trimesh.creation.torus(major, tube_radius, major_sections=64, minor_sections=20)
    torus.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0]))
    torus.apply_translation([attach_radius + offset, 0.0, centre_z])
    return torus


def box_at(extents, centre) -> object:
    """An axis-aligned box of ``extents`` (m) centred at ``centre``."""
    import trimesh

    box = trimesh.creation.box(extents=extents)
    box.apply_translation(centre)
    return box


def cylinder_x(radius, length, centre) -> object:
    """A cylinder along x."""
    import trimesh

    cylinder = trimesh.creation.cylinder(radius=radius, height=length, sections=32)
    cylinder.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0]))
    cylinder.apply_translation(centre)
    return cylinder


def smooth_step(t):
    """0 below 0, 1 above 1, a half cosine between (zero slope at both ends)."""
    t = np.clip(t, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(math.pi * t)


def uniform(rng, low, high) -> float:
    """One draw from [low, high) of ``rng`` (a parameter sampler's unit: metres, unless it says otherwise)."""
    return float(rng.uniform(low, high))


# --------------------------------------------------------------------------- helpers of the shape families
# (objects/kitchen_families.py, tool_families.py, organic_families.py; none of the original twelve uses them)


def hull(points) -> object:
    """The convex hull of ``points`` (m): a closed convex solid (flat blades, bars, chamfered boxes)."""
    import trimesh

    return trimesh.convex.convex_hull(np.asarray(points, dtype=np.float64))


def sphere_points(radius: float, centre, subdivisions: int = 2) -> np.ndarray:
    """Vertices of an icosphere of ``radius`` about ``centre``: hulls of several make rounded boxes and bars."""
    import trimesh

    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius).vertices + np.asarray(centre, dtype=np.float64)


def rounded_box(extents, radius: float, centre, subdivisions: int = 2) -> object:
    """A box of ``extents`` (m) whose edges and corners are rounded with ``radius`` (hull of eight corner spheres)."""
    half = np.asarray(extents, dtype=np.float64) / 2 - radius
    corners = [np.asarray(centre, dtype=np.float64) + half * (np.array(signs) * 2 - 1) for signs in np.ndindex(2, 2, 2)]
    return hull(np.vstack([sphere_points(radius, c, subdivisions) for c in corners]))


def chamfered_box(extents, chamfer: float, centre) -> object:
    """A box of ``extents`` (m) with every edge cut at 45° by ``chamfer`` (hull of three points per corner)."""
    half = np.asarray(extents, dtype=np.float64) / 2
    points = []
    for signs in np.ndindex(2, 2, 2):
        corner = half * (np.array(signs) * 2 - 1)
        for axis in range(3):
            point = corner.copy()
            point[axis] -= np.sign(corner[axis]) * chamfer
            points.append(point)
    return hull(np.array(points) + np.asarray(centre, dtype=np.float64))


def rod_between(start, end, radius: float, sections: int = 24, rounded: bool = True) -> object:
    """A rod of ``radius`` (m) from ``start`` to ``end``: a capsule (hemispherical ends) or a flat-ended cylinder."""
    import trimesh

    start, end = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
    axis = end - start
    length = float(np.linalg.norm(axis))
    if rounded:
        rod = trimesh.creation.capsule(height=length, radius=radius, count=[sections, sections // 2 + 1])
    else:
        rod = trimesh.creation.cylinder(radius=radius, height=length, sections=sections)
    transform = trimesh.geometry.align_vectors([0.0, 0.0, 1.0], axis / length)
    transform[:3, 3] = (start + end) / 2
    rod.apply_transform(transform)
    return rod


def to_trimesh(manifold) -> object:
    """A manifold3d ``Manifold`` as a ``trimesh.Trimesh`` (its first three vertex properties are positions), unprocessed:
    merging near vertices could pinch the manifold surface that marching tetrahedra make."""
    import trimesh

    mesh = manifold.to_mesh()
    return trimesh.Trimesh(np.asarray(mesh.vert_properties)[:, :3].astype(np.float64), np.asarray(mesh.tri_verts), process=False)


def implicit_solid(inside, bounds, edge: float) -> object:
    """The solid where the scalar function ``inside(x, y, z)`` (m; positive inside, roughly a signed distance) is
    positive, within ``bounds`` ([x0, y0, z0, x1, y1, z1]), meshed by manifold3d's marching tetrahedra with edges of
    about ``edge`` (m): closed and manifold by construction. Used for blended organic blobs (a toy figure)."""
    import manifold3d

    return to_trimesh(manifold3d.Manifold.level_set(inside, list(map(float, bounds)), float(edge)))


def smooth_min(a: float, b: float, blend: float) -> float:
    """Polynomial smooth minimum of two distances: a fillet of about ``blend`` (m) where two blobs meet."""
    h = max(blend - abs(a - b), 0.0) / blend
    return min(a, b) - h * h * blend * 0.25


def star_solid(radius_of, subdivisions: int = 4) -> object:
    """A closed solid whose surface is at distance ``radius_of(directions)`` (m, positive, smooth) from the origin along
    each unit direction of an icosphere: star-shaped organic forms (fruit) without booleans; 2562 vertices at 4."""
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    directions = np.asarray(sphere.vertices)
    radii = np.asarray(radius_of(directions), dtype=np.float64)
    return trimesh.Trimesh(directions * radii[:, None], sphere.faces, process=True)


def flatten_below(mesh, z_cut: float):
    """``mesh`` with every vertex below ``z_cut`` raised onto it: a flat resting face where a round bottom met the table
    (valid where the part below the plane is a single-valued graph over it, as for fruit bottoms)."""
    vertices = np.array(mesh.vertices)
    vertices[:, 2] = np.maximum(vertices[:, 2], z_cut)
    mesh.vertices = vertices
    return mesh


def swept_tube(centres, radii, section=None, up=(0.0, 0.0, 1.0), sides: int = 24) -> object:
    """A closed tube along the polyline ``centres`` (m) with radius ``radii`` at each centre (tapering to points at the
    ends is fine: the ends are closed by a fan to the end centre). ``section(angles)`` scales the radius around the
    tube (e.g. a banana's five faint ridges); ``up`` fixes the frame's roll. Watertight by construction."""
    import trimesh

    centres = np.asarray(centres, dtype=np.float64)
    tangents = np.gradient(centres, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    normals = np.cross(tangents, np.asarray(up, dtype=np.float64))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    binormals = np.cross(tangents, normals)
    angles = np.linspace(0.0, 2 * math.pi, sides, endpoint=False)
    scale = np.ones(sides) if section is None else np.asarray(section(angles))
    offsets = np.cos(angles)[None, :, None] * normals[:, None, :] + np.sin(angles)[None, :, None] * binormals[:, None, :]
    rings = centres[:, None, :] + (np.asarray(radii)[:, None] * scale[None, :])[:, :, None] * offsets
    n = len(centres)
    vertices = np.vstack([rings.reshape(-1, 3), centres[0], centres[-1]])
    faces = []
    for i in range(n - 1):
        for j in range(sides):
            a, b = i * sides + j, i * sides + (j + 1) % sides
            faces += [[a, b, b + sides], [a, b + sides, a + sides]]
    first, last = n * sides, n * sides + 1
    faces += [[first, (j + 1) % sides, j] for j in range(sides)]
    faces += [[last, (n - 1) * sides + j, (n - 1) * sides + (j + 1) % sides] for j in range(sides)]
    mesh = trimesh.Trimesh(vertices, np.array(faces), process=True)
    if mesh.volume < 0:
        mesh.invert()
    return mesh
