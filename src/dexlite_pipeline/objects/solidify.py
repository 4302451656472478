"""One closed solid from a mesh file as people have them: one shell, several shells, convex-piece sets, scans.

``solid_from_mesh`` decides what the file's bodies are, refuses a file holding several
objects, sets aside tiny floating fragments (recorded), and makes the rest one solid by the
most exact route that works:

1. one body: seams welded, holes filled (trimesh, then MeshFix), normals made consistent;
2. several closed bodies (overlapping or touching shells, convex pieces as CoACD and V-HACD
   write them): their boolean union (the manifold engine);
3. anything else (open or non-manifold pieces, internal faces, a union that failed or that
   ``objects.fidelity`` finds is not the input, such as one keeping walls between touching pieces): a
   volumetric remesh (``objects.remesh``): inside is where the generalized winding number of
   the input exceeds 1/2 (robust to holes, overlaps, flipped shells and internal faces), the
   field's magnitude is the exact distance to the input surface, and marching cubes extracts
   its zero level on a grid tied to the object's size.

``objects.fidelity`` then measures how far the solid is from the input surface.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dexlite_pipeline.objects.remesh import clean_faces, volumetric_remesh, winding_numbers

# Vertices closer than this fraction of the bounding-box diagonal are one vertex (welded seams):
# 14 µm on a 14 cm object, far below the SDF grid and the surface sampling.
WELD_TOLERANCE = 1e-4
# Bodies whose surfaces come closer than this fraction of the whole file's bounding-box diagonal
# belong to one object (touching pieces, a cap on a bottle); farther apart, they are separate objects.
CONTACT_GAP = 0.02
# A group of bodies whose bounding-box diagonal is under this fraction of the largest group's is a
# floating fragment (scan debris, a stray triangle): set aside and recorded, not an object of its own.
FRAGMENT_SIZE = 0.05
# Files with more components than this (on the file's own vertex indices) are triangle soups
# (STL), whose bodies appear only after welding.
MAX_FILE_BODIES = 4096
# Surface points per body when measuring gaps between bodies (at most MAX_GAP_SAMPLES in all).
GAP_SAMPLES_PER_BODY = 400
MAX_GAP_SAMPLES = 40_000


SINGLE_SHELL = "single shell"
UNION = "union of closed bodies"
VOLUMETRIC = "volumetric remesh"


class SeveralObjects(ValueError):
    """The file holds more than one object (bodies far apart); the message says how many and how far."""


@dataclass
class SolidRecord:
    """How a file became one solid: its bodies, what was set aside, the route taken."""

    bodies_in_file: int
    route: str  # SINGLE_SHELL, UNION or VOLUMETRIC
    bodies_kept: int
    fragments_set_aside: int = 0
    largest_fragment: float = 0.0  # bounding-box diagonal of the largest fragment set aside / the object's
    input_is_closed: bool = True  # every kept body is a closed surface (for the fidelity check's second side)
    notes: list[str] = field(default_factory=list)

    def summary(self) -> str:
        """One line for the catalog and logs."""
        text = f"{self.route} of {self.bodies_kept} bod{'y' if self.bodies_kept == 1 else 'ies'}"
        if self.bodies_in_file != self.bodies_kept:
            text += f" ({self.bodies_in_file} in the file)"
        if self.fragments_set_aside:
            text += (f"; {self.fragments_set_aside} floating fragment(s) set aside (largest "
                     f"{100 * self.largest_fragment:.1f}% of the object's size)")  # fmt: skip
        return text


def weld_vertices(mesh, tolerance: float):
    """Merge vertices closer than ``tolerance`` (mesh units) into one, so split seams become shared edges.

    Exporters often duplicate the vertices of a seam (UV or normal seams, STL triangle
    soups, coordinates printed with few digits) so that the two sides of the seam are not
    connected and each looks like the edge of a hole. Exact duplicates are merged by
    trimesh; this also merges near-duplicates, as clusters of points within ``tolerance``
    of a neighbour. Faces that collapse are removed by the caller.
    """
    import trimesh
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    pairs = cKDTree(vertices).query_pairs(tolerance, output_type="ndarray")
    if len(pairs) == 0:
        return mesh
    n = len(vertices)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    # Each cluster becomes its mean position; faces are re-indexed onto the clusters.
    counts = np.bincount(label)
    merged = np.zeros((counts.size, 3))
    np.add.at(merged, label, vertices)
    merged /= counts[:, None]
    return trimesh.Trimesh(merged, label[np.asarray(mesh.faces)], process=False)


def welded(mesh, diagonal: float):
    """``mesh`` with exact and near-duplicate vertices merged (tolerance relative to ``diagonal``) and bad faces removed."""
    import trimesh

    mesh = trimesh.Trimesh(mesh.vertices, mesh.faces, process=True)
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    if len(mesh.vertices):
        mesh = weld_vertices(mesh, WELD_TOLERANCE * diagonal)
    return clean_faces(mesh)


def _close_with_meshfix(mesh):
    """Fill every hole (and remove self-intersections) with MeshFix, keeping every component.

    MeshFix (Attene, via the ``pymeshfix`` package) fills each boundary loop with a
    triangulated, refined patch that follows the surrounding surface, and cleans
    degenerate or self-intersecting triangles it finds on the way.
    """
    import pymeshfix
    import trimesh

    fixer = pymeshfix.MeshFix(np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int32))
    fixer.repair(joincomp=False, remove_smallest_components=False)
    return trimesh.Trimesh(np.asarray(fixer.points), np.asarray(fixer.faces), process=False)


def repaired_shell(mesh):
    """One body with its holes filled and its winding and normals made consistent (may still be open).

    Small holes (triangles, quads) are filled by trimesh; anything still open (open
    bottoms of scans, larger or irregular holes, boundaries that touch themselves) is
    closed by MeshFix, whose result is kept only if it is a closed solid.
    """
    import trimesh

    if len(mesh.faces) == 0:
        return mesh
    trimesh.repair.fix_winding(mesh)
    if not mesh.is_watertight:
        trimesh.repair.fill_holes(mesh)
    if not mesh.is_watertight:
        closed = clean_faces(_close_with_meshfix(mesh))
        trimesh.repair.fix_normals(closed, multibody=True)
        if closed.is_watertight and closed.volume > 0:
            mesh = closed
    trimesh.repair.fix_normals(mesh, multibody=True)
    return mesh


def consistently_wound(body):
    """A copy of ``body`` with its faces' winding made consistent (nothing added: holes stay holes for the winding number)."""
    import trimesh

    body = body.copy()
    trimesh.repair.fix_winding(body)
    return body


def _file_bodies(raw, diagonal: float) -> list | None:
    """The file's own bodies (components over its vertex indices, each welded on its own), if there are several
    and every one is closed; else None (one body, a triangle soup, or open pieces: bodies come from welding)."""
    import trimesh

    labels = trimesh.graph.connected_component_labels(trimesh.Trimesh(raw.vertices, raw.faces, process=False).face_adjacency,
                                                      node_count=len(raw.faces))
    count = int(labels.max()) + 1 if len(labels) else 0
    if count < 2 or count > MAX_FILE_BODIES:
        return None
    faces = np.asarray(raw.faces)
    bodies = []
    for label in range(count):
        body = welded(trimesh.Trimesh(raw.vertices, faces[labels == label], process=False), diagonal)
        if len(body.faces) == 0:
            continue
        if not body.is_watertight:
            return None
        trimesh.repair.fix_normals(body)
        bodies.append(body)
    return bodies if len(bodies) >= 2 else None


def _surface_points(mesh, count: int) -> np.ndarray:
    """Its vertices and ``count`` evenly spaced surface points (deterministic), for gap measurements."""
    import trimesh

    points = trimesh.sample.sample_surface(mesh, count, seed=0)[0] if mesh.area > 0 else np.empty((0, 3))
    return np.vstack([np.asarray(mesh.vertices), points])


def _body_groups(bodies: list, diagonal: float) -> list[list[int]]:
    """Bodies that touch, overlap or nest (closer than ``CONTACT_GAP`` of ``diagonal``) grouped together."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    n = len(bodies)
    gap = CONTACT_GAP * diagonal
    per_body = max(16, min(GAP_SAMPLES_PER_BODY, MAX_GAP_SAMPLES // n))
    lows = np.array([b.bounds[0] for b in bodies]) - gap
    highs = np.array([b.bounds[1] for b in bodies]) + gap
    near = np.all((lows[:, None, :] <= highs[None, :, :]) & (lows[None, :, :] <= highs[:, None, :]), axis=2)
    pairs = np.argwhere(np.triu(near, k=1))
    points = [None] * n
    trees = [None] * n

    def tree(i):
        if trees[i] is None:
            points[i] = _surface_points(bodies[i], per_body)
            trees[i] = cKDTree(points[i])
        return trees[i]

    linked = []
    for i, j in pairs:
        tree(i), tree(j)
        close = trees[i].sparse_distance_matrix(trees[j], gap, output_type="ndarray")
        if len(close):
            linked.append((i, j))
            continue
        # one inside the other without touching (a shell in a shell): the outer's winding number at the inner's points
        for outer, inner in ((i, j), (j, i)):
            if bodies[outer].is_watertight:
                if winding_numbers(bodies[outer].vertices, bodies[outer].faces, points[inner][:8]).max() > 0.5:
                    linked.append((i, j))
                    break
    if linked:
        edges = np.array(linked)
        graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    else:
        graph = coo_matrix((n, n))
    _, label = connected_components(graph, directed=False)
    return [list(np.flatnonzero(label == g)) for g in range(label.max() + 1)]


def _bounds_diagonal(meshes: list) -> float:
    lo = np.min([m.bounds[0] for m in meshes], axis=0)
    hi = np.max([m.bounds[1] for m in meshes], axis=0)
    return float(np.linalg.norm(hi - lo))


def one_object(bodies: list, diagonal: float) -> tuple[list, int, float]:
    """The bodies of the file's one object, the number of floating fragments set aside and the largest one's relative size.

    Raises ``SeveralObjects`` when groups of comparable size lie apart: a file with two objects
    is not glued into one.
    """
    if len(bodies) == 1:
        return bodies, 0, 0.0
    groups = _body_groups(bodies, diagonal)
    if len(groups) == 1:
        return bodies, 0, 0.0
    sizes = np.array([_bounds_diagonal([bodies[i] for i in g]) for g in groups])
    main = int(np.argmax(sizes))
    objects = [g for g, s in zip(groups, sizes) if s >= FRAGMENT_SIZE * sizes[main]]
    if len(objects) > 1:
        raise SeveralObjects(
            f"{len(objects)} separate objects in one file ({len(bodies)} bodies, the objects more than "
            f"{100 * CONTACT_GAP:g}% of the file's size apart): give one object per file"
        )  # fmt: skip
    fragments = [s for k, s in enumerate(sizes) if k != main]
    return [bodies[i] for i in groups[main]], len(fragments), float(max(fragments) / sizes[main])


def union_of_closed_bodies(bodies: list):
    """The boolean union of closed bodies (manifold engine), or None when it fails or is not a closed solid."""
    import trimesh

    try:
        union = trimesh.boolean.union(bodies, engine="manifold")
    except Exception:  # noqa: BLE001 - the engine refused the input: the caller falls back to the remesh
        return None
    return union if union.is_watertight and union.is_winding_consistent and union.volume > 0 else None


def solid_from_mesh(raw) -> tuple[object, SolidRecord, list]:
    """One closed solid from the file's mesh ``raw`` (placed, not yet repaired), how it was made, and the input's
    bodies it stands for (the file's bodies without floating fragments, as read: for ``objects.fidelity``).

    Raises ``SeveralObjects`` for a file holding several objects. The result may still be open when
    nothing could close it (the caller's check refuses it with its open-edge count).
    """
    import trimesh

    diagonal = float(np.linalg.norm(raw.extents)) if len(raw.vertices) else 0.0
    file_bodies = _file_bodies(raw, diagonal)
    if file_bodies is None:
        mesh = welded(raw, diagonal)
        bodies = mesh.split(only_watertight=False) if len(mesh.faces) and mesh.body_count > 1 else [mesh]
    else:
        bodies = file_bodies
    in_file = len(bodies)
    bodies, fragments, largest = one_object(bodies, diagonal)
    record = SolidRecord(in_file, SINGLE_SHELL, len(bodies), fragments, largest)
    kept = [b.copy() for b in bodies]
    if len(bodies) == 1:
        record.input_is_closed = bool(bodies[0].is_watertight)
        shell = repaired_shell(bodies[0])
        if shell.is_watertight or len(shell.faces) == 0:
            return shell, record, kept
        record.route = VOLUMETRIC
        return volumetric_remesh([consistently_wound(body) for body in kept], record.input_is_closed), record, kept
    record.input_is_closed = all(body.is_watertight for body in bodies)
    if record.input_is_closed:
        for body in bodies:
            trimesh.repair.fix_normals(body)
        union = union_of_closed_bodies(bodies)
        if union is not None:
            record.route = UNION
            return union, record, kept
    record.route = VOLUMETRIC
    return volumetric_remesh([consistently_wound(body) for body in kept], record.input_is_closed), record, kept

