"""The volumetric remesh: the solid a set of bodies encloses, whatever their defects, on a grid tied to its size.

Inside is where the generalized winding number of the bodies together exceeds 1/2 (robust to
holes, overlaps, flipped shells and internal faces); the field's magnitude is the exact
distance to their surface; marching cubes extracts the zero level, which lies on the input
surface to well under a voxel where that is smooth. Used by ``objects.solidify`` for what no
exact route makes one solid.
"""

from __future__ import annotations

import numpy as np

# The volumetric remesh's grid: this many voxels along the largest extent (0.75 mm on a 12 cm object).
REMESH_VOXELS = 160
# The remesh is decimated to at most this many faces (where it stays closed).
REMESH_MAX_FACES = 20_000
# Within this many voxels of the surface the remesh evaluates distance and winding number exactly
# (farther, no surface lies between a node and its nearest coarse node, at most 2 sqrt(3) voxels away).
NEAR = 3.5
# Nodes at which the winding number is read per connected region of nodes away from the surface.
COMPONENT_PROBES = 16


def clean_faces(mesh):
    """The mesh without degenerate or repeated faces and unreferenced vertices."""
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.update_faces(mesh.unique_faces())
    mesh.remove_unreferenced_vertices()
    return mesh


def winding_numbers(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """|generalized winding number| of the surface at ``points`` (1 inside a closed shell, 0 outside, either orientation)."""
    import igl

    return np.abs(igl.fast_winding_number(np.asarray(vertices, np.float64), np.asarray(faces, np.int64), np.asarray(points, np.float64)))


def _grid(lo: np.ndarray, counts: np.ndarray, voxel: float, step: int = 1) -> np.ndarray:
    """Nodes of the grid with ``counts`` nodes per axis from ``lo`` (every ``step``-th), x fastest."""
    axes = [lo[k] + voxel * np.arange(0, counts[k], step) for k in range(3)]
    gz, gy, gx = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    return np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1)


def _one_node_slits(inside: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Outside nodes with inside nodes on both sides along x, y or z: gaps thinner than two voxels between pieces."""
    grid = inside.reshape(counts[2], counts[1], counts[0])
    slit = np.zeros_like(grid)
    for axis in range(3):
        before = np.roll(grid, 1, axis=axis)
        after = np.roll(grid, -1, axis=axis)
        slit |= before & after  # the grid's border nodes are outside (3 voxels of padding), so rolling over is harmless
    return (slit & ~grid).ravel()


def _enclosed(outside: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Outside nodes that no path of outside nodes joins to the grid's border: voids inside the solid (nodes that fell
    into the thin gaps between touching pieces), to be filled."""
    from scipy import ndimage

    grid = outside.reshape(counts[2], counts[1], counts[0])
    label, _ = ndimage.label(grid)
    border = np.unique(np.concatenate([label[[0, -1]].ravel(), label[:, [0, -1]].ravel(), label[:, :, [0, -1]].ravel()]))
    return (grid & ~np.isin(label, border)).ravel()


def _component_signs(free: np.ndarray, counts: np.ndarray, inside_at) -> np.ndarray:
    """Inside flags of the ``free`` nodes, one per 6-connected component of them, read at a few of its nodes.

    For a closed input no surface passes between two adjacent free nodes (both more than half a
    voxel from it), so a component is all inside or all outside; where the nodes read disagree
    (never for a closed input) every node of that component is read.
    """
    from scipy import ndimage

    label, count = ndimage.label(free.reshape(counts[2], counts[1], counts[0]))
    label = label.ravel()
    inside = np.zeros(label.size, dtype=bool)
    order = np.argsort(label, kind="stable")
    starts = np.searchsorted(label[order], np.arange(1, count + 2))
    rng = np.random.default_rng(0)
    for component in range(count):
        members = order[starts[component]:starts[component + 1]]
        probe = members if len(members) <= COMPONENT_PROBES else rng.choice(members, COMPONENT_PROBES, replace=False)
        flags = inside_at(probe)
        if flags.all() or not flags.any():
            inside[members] = flags[0]
        else:
            inside[members] = inside_at(members)
    return inside[free]


def volumetric_remesh(bodies: list, closed: bool = False, voxels: int | None = None):
    """The solid the bodies enclose, remeshed on a grid of ``voxels`` (default ``REMESH_VOXELS``) cells along the largest extent.

    Inside: |winding number| > 1/2 of all bodies together; value: the exact unsigned distance to
    their surface (negative inside, at least a thousandth of a voxel so internal faces leave no
    zero level), voids filled; marching cubes at 0 puts the surface on the input's, to well under a voxel
    where the surface is smooth. The distance is exact within ``NEAR`` voxels of the surface and a
    lower bound farther out (where marching cubes never reads it: no sign change there). The
    winding number is read at every node within half a voxel of a ``closed`` input's surface and
    once per connected region of the other nodes (``_component_signs``); for an open input (whose
    inside and outside meet at its holes) at every node within ``NEAR`` voxels, farther out from the
    nearest node of a 4x coarser grid, which no surface separates from the point.
    """
    import igl
    import trimesh

    soup = trimesh.util.concatenate(bodies) if len(bodies) > 1 else bodies[0]
    vertices, faces = np.asarray(soup.vertices, np.float64), np.asarray(soup.faces, np.int64)

    def inside_at(nodes):
        return winding_numbers(vertices, faces, points[nodes]) > 0.5

    lo, hi = soup.bounds
    voxel = float((hi - lo).max()) / (voxels or REMESH_VOXELS)
    coarse = 4
    lo = lo - 3 * voxel
    counts = np.ceil((hi + 3 * voxel - lo) / voxel / coarse).astype(int) * coarse + 1  # coarse nodes fall on fine ones
    coarse_counts = (counts - 1) // coarse + 1
    coarse_points = _grid(lo, counts, voxel, coarse)
    coarse_distance = np.sqrt(igl.point_mesh_squared_distance(coarse_points, vertices, faces)[0])
    points = _grid(lo, counts, voxel)
    index = np.round((points - lo) / voxel).astype(np.int64)
    nearest = np.round(index / coarse).astype(np.int64)
    offset = np.linalg.norm(index - nearest * coarse, axis=1) * voxel
    flat = nearest[:, 0] + coarse_counts[0] * (nearest[:, 1] + coarse_counts[1] * nearest[:, 2])
    distance = np.maximum(coarse_distance[flat] - offset, 0.0)
    near = np.flatnonzero(distance < NEAR * voxel)
    distance[near] = np.sqrt(igl.point_mesh_squared_distance(points[near], vertices, faces)[0])
    if closed:
        surface = distance <= 0.5 * voxel
        inside = np.zeros(len(points), dtype=bool)
        inside[surface] = inside_at(np.flatnonzero(surface))
        inside[~surface] = _component_signs(~surface, counts, inside_at)
    else:
        inside = (winding_numbers(vertices, faces, coarse_points) > 0.5)[flat]
        inside[near] = inside_at(near)
    # nodes on the input surface (cut faces shared by touching pieces) are inside, as are slits one node wide
    # between pieces that do not quite touch and voids that no outside path reaches
    inside |= distance < 1e-2 * voxel
    inside |= _one_node_slits(inside, counts)
    inside |= _enclosed(~inside, counts)
    value = np.where(inside, -np.maximum(distance, 1e-3 * voxel), np.maximum(distance, 1e-3 * voxel))
    out_vertices, out_faces, _ = igl.marching_cubes(value, points, int(counts[0]), int(counts[1]), int(counts[2]), 0.0)
    mesh = _decimated(clean_faces(trimesh.Trimesh(out_vertices, out_faces, process=True)))
    trimesh.repair.fix_normals(mesh, multibody=True)
    return mesh


def _decimated(mesh):
    """``mesh`` simplified to ``REMESH_MAX_FACES`` faces (quadric decimation, fast-simplification) when it has more and the
    result is still closed; marching cubes' many small faces would slow the convex decomposition and SDF grid for
    nothing (the fidelity check measures the result)."""
    import fast_simplification
    import trimesh

    if len(mesh.faces) <= REMESH_MAX_FACES:
        return mesh
    vertices, faces = fast_simplification.simplify(np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces, np.int32),
                                                   target_reduction=1.0 - REMESH_MAX_FACES / len(mesh.faces))  # fmt: skip
    simple = clean_faces(trimesh.Trimesh(np.asarray(vertices, np.float64), faces, process=True))
    return simple if simple.is_watertight and simple.is_winding_consistent else mesh
