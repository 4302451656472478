"""Meshes in the forms people have them, made here (no download): for the preparation's tests and checks.

Each builder returns ``(input mesh, intended solid)`` in metres: the file as a user would hand
it over (several bodies, open scans, flipped faces, debris ...) and the one closed solid it
stands for, which preparation must reproduce or refuse. ``None`` as the intended solid means
the input must be refused (two objects in one file, a flat sheet).
"""

from __future__ import annotations

import numpy as np

from dexlite_pipeline.objects.household import CHECK_OBJECTS, build_can, build_family
from dexlite_pipeline.objects.household_shapes import revolve


def concatenated(meshes):
    """One mesh holding every body of ``meshes`` (vertices not shared), as a multi-object .obj is read."""
    import trimesh

    return trimesh.util.concatenate([m.copy() for m in meshes])


def slab_sector_pieces(convex_mesh, n_slabs: int, n_sectors: int) -> list:
    """A convex mesh cut into ``n_slabs`` slabs along z times ``n_sectors`` sectors about z: exact convex pieces that touch.

    The pieces of a V-HACD / CoACD file of a convex object: closed, convex, sharing their cut faces.
    """
    import trimesh
    from scipy.spatial import ConvexHull, HalfspaceIntersection

    hull = ConvexHull(np.asarray(convex_mesh.vertices))
    lo, hi = convex_mesh.bounds
    z_cuts = np.linspace(lo[2], hi[2], n_slabs + 1)
    centre = (lo + hi) / 2
    pieces = []
    for k in range(n_slabs):
        for s in range(n_sectors):
            a0, a1 = 2 * np.pi * s / n_sectors, 2 * np.pi * (s + 1) / n_sectors
            # halfspaces as [normal, offset] with normal . x + offset <= 0
            cuts = [
                [0.0, 0.0, -1.0, z_cuts[k]],
                [0.0, 0.0, 1.0, -z_cuts[k + 1]],
                [np.sin(a0), -np.cos(a0), 0.0, -(np.sin(a0) * centre[0] - np.cos(a0) * centre[1])],
                [-np.sin(a1), np.cos(a1), 0.0, np.sin(a1) * centre[0] - np.cos(a1) * centre[1]],
            ]
            halfspaces = np.vstack([hull.equations, np.asarray(cuts)])
            inner = centre + np.array([np.cos((a0 + a1) / 2), np.sin((a0 + a1) / 2), 0.0]) * 0.3 * (hi[0] - lo[0]) / 2
            inner[2] = (z_cuts[k] + z_cuts[k + 1]) / 2
            corners = HalfspaceIntersection(halfspaces, inner).intersections
            pieces.append(trimesh.convex.convex_hull(corners))
    return pieces


def coacd_pieces(mesh, threshold: float = 0.05, seed: int = 0) -> list:
    """CoACD's convex pieces of ``mesh`` (what a simulator-ready object file holds)."""
    import coacd
    import trimesh

    coacd.set_log_level("error")
    parts = coacd.run_coacd(coacd.Mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces)), threshold=threshold, seed=seed)
    return [trimesh.Trimesh(v, f, process=True) for v, f in parts]


def check_can():
    """A drinks can 8.4 cm wide and 12 cm tall (metres), one closed shell."""
    return build_can(0.12, 0.042)


def can_as_convex_pieces():
    """The can as 32 touching convex pieces (4 slabs x 8 sectors) in one file."""
    can = check_can()
    return concatenated(slab_sector_pieces(can, 4, 8)), can


def mug_as_convex_pieces():
    """The check mug (4 mm wall, handle) as CoACD's convex pieces in one file (about 25 pieces; ~10 s)."""
    mug = build_family(*CHECK_OBJECTS["mug"])
    return concatenated(coacd_pieces(mug)), mug


BOTTLE_PROFILE = [[0.0, 0.0], [0.035, 0.0], [0.035, 0.14], [0.013, 0.18], [0.013, 0.2], [0.015, 0.2], [0.015, 0.22], [0.0, 0.22]]


def one_shell_bottle():
    """A 22 cm bottle: body, shoulder, neck and cap as one closed shell."""
    return revolve(BOTTLE_PROFILE)


def three_shell_bottle():
    """The bottle as three closed bodies stacked and touching: body (0-14 cm), shoulder and neck (14-20 cm), cap (20-22 cm)."""
    body = revolve([[0.0, 0.0], [0.035, 0.0], [0.035, 0.14], [0.0, 0.14]])
    shoulder = revolve([[0.0, 0.14], [0.035, 0.14], [0.013, 0.18], [0.013, 0.2], [0.0, 0.2]])
    cap = revolve([[0.0, 0.2], [0.015, 0.2], [0.015, 0.22], [0.0, 0.22]])
    return concatenated([body, shoulder, cap]), one_shell_bottle()


def overlapping_shells():
    """A 10 cm box and a cylinder through it, two closed shells that overlap (a CAD export of an unmerged assembly)."""
    import trimesh

    box = trimesh.creation.box((0.1, 0.06, 0.05))
    rod = trimesh.creation.cylinder(radius=0.015, height=0.16, sections=48)
    rod.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    return concatenated([box, rod]), trimesh.boolean.union([box, rod], engine="manifold")


def duplicate_shells():
    """The can's shell written twice (an exporter that repeats a body)."""
    can = check_can()
    return concatenated([can, can]), can


def open_bottom_scan():
    """A scan-like cylinder (8 cm wide, 10 cm tall): no bottom, 0.3 mm noise on every vertex."""
    import trimesh

    solid = trimesh.creation.cylinder(radius=0.04, height=0.1, sections=64)
    solid = solid.subdivide().subdivide()
    keep = ~(solid.face_normals[:, 2] < -0.99)
    noise = np.random.default_rng(7).normal(0.0, 0.0003, solid.vertices.shape)
    scan = trimesh.Trimesh(solid.vertices + noise, solid.faces[keep], process=False)
    scan.remove_unreferenced_vertices()
    return scan, solid


def inverted_normals():
    """The one-shell bottle with every face turned inside out."""
    import trimesh

    bottle = one_shell_bottle()
    return trimesh.Trimesh(bottle.vertices, bottle.faces[:, ::-1], process=False), bottle


def internal_faces():
    """A 12 x 6 x 4 cm box with an internal partition wall (two triangles spanning its middle)."""
    import trimesh

    box = trimesh.creation.box((0.12, 0.06, 0.04))
    wall = np.array([[0.0, -0.03, -0.02], [0.0, 0.03, -0.02], [0.0, 0.03, 0.02], [0.0, -0.03, 0.02]])
    vertices = np.vstack([box.vertices, wall])
    n = len(box.vertices)
    faces = np.vstack([box.faces, [[n, n + 1, n + 2], [n, n + 2, n + 3]]])
    return trimesh.Trimesh(vertices, faces, process=False), box


def cad_box_in_millimetres():
    """A 120 x 80 x 40 box in millimetres as two 60 mm halves sharing their inner face (non-manifold edges after welding)."""
    import trimesh

    left = trimesh.creation.box((60.0, 80.0, 40.0))
    left.apply_translation([-30.0, 0.0, 0.0])
    right = trimesh.creation.box((60.0, 80.0, 40.0))
    right.apply_translation([30.0, 0.0, 0.0])
    return concatenated([left, right]), trimesh.creation.box((120.0, 80.0, 40.0))


def floating_debris():
    """The can with four tiny tetrahedra (under 1.5 mm) floating a few centimetres away."""
    import trimesh

    can = check_can()
    debris = []
    for i, offset in enumerate([(0.08, 0, 0.02), (-0.07, 0.03, 0.05), (0.0, 0.09, 0.1), (0.02, -0.08, 0.0)]):
        tetra = trimesh.creation.icosphere(subdivisions=0, radius=0.0007 + 0.0001 * i)
        tetra.apply_translation(offset)
        debris.append(tetra)
    return concatenated([can, *debris]), can


def two_objects_far_apart():
    """Two cans 30 cm apart in one file: two objects, not one."""
    first, second = check_can(), check_can()
    second.apply_translation([0.3, 0.0, 0.0])
    return concatenated([first, second]), None


def near_flat_sheet():
    """A 20 x 20 cm sheet 10 µm thick: nothing a hand can close on."""
    import trimesh

    return trimesh.creation.box((0.2, 0.2, 0.00001)), None


# name -> (builder, units of the builder's coordinates)
CORPUS = {
    "can_convex_pieces": (can_as_convex_pieces, "m"),
    "mug_convex_pieces": (mug_as_convex_pieces, "m"),
    "three_shell_bottle": (three_shell_bottle, "m"),
    "overlapping_shells": (overlapping_shells, "m"),
    "duplicate_shells": (duplicate_shells, "m"),
    "open_bottom_scan": (open_bottom_scan, "m"),
    "inverted_normals": (inverted_normals, "m"),
    "internal_faces": (internal_faces, "m"),
    "cad_box_mm": (cad_box_in_millimetres, "mm"),
    "floating_debris": (floating_debris, "m"),
    "two_objects_far_apart": (two_objects_far_apart, "m"),
    "near_flat_sheet": (near_flat_sheet, "m"),
}
