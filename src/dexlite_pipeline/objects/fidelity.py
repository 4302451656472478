"""Is the prepared solid the input? Bounding box, volume and surface distance between the two, relative to the size.

Measured on the object's bodies as kept (floating fragments set aside are recorded apart, by
``objects.solidify``), in the file's units after placement:

- **surface distance**, two-sided: the 99th percentile of the distances from points spread
  over the input's *outer* surface to the prepared surface (data lost: a dropped cap, a shell
  reduced to a sliver), and from points on the prepared surface to the input surface (material
  added: bodies glued, shapes bridged, walls left inside the solid). Input points with solid on
  both sides of them (internal faces, the cut faces between convex pieces) are not outer
  surface. The second side is measured only where the input is closed: a filled hole is on the
  prepared surface and not on an open input;
- **bounding box**: the largest difference of the two boxes' corners (the input's over its kept bodies);
- **volume**: the input's (exact for one closed shell, else estimated by the winding number
  at seeded random points) against the prepared solid's, where the input is closed.

The size is the input's largest bounding-box extent. ``objects.prepare`` refuses an object
whose deviation exceeds the tolerances below and records the deviation of every object.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass

import numpy as np

from dexlite_pipeline.objects.remesh import winding_numbers

log = logging.getLogger(__name__)
# Tolerances (fractions of the input's largest extent). Chosen on the awkward-mesh corpus
# (objects.mesh_forms) and pybullet_data's multi-piece objects (docs/results_journal.md): correct
# preparations stay under a quarter of the surface and box tolerances and within 3% on the volume
# (the estimate for several bodies is a sampled one); every wrong shape the earlier preparation
# made exceeded one of them 5x or more.
MAX_SURFACE_P99 = 0.02
MAX_BOUNDS_ERROR = 0.02
MAX_VOLUME_ERROR = 0.05
# Surface distances at or below this many metres always pass (a millimetre-scale floor for small objects),
# when the file's unit is known.
SURFACE_FLOOR_M = 0.001
SAMPLES = 20_000
VOLUME_SAMPLES = 60_000
# Offset (fraction of the size) at which the two sides of an input surface point are probed.
SIDE_PROBE = 2e-4


@dataclass
class ShapeDeviation:
    """How far the prepared solid is from the input (fractions of ``size``, the input's largest extent)."""

    size: float  # file units
    surface_p99_in_to_prepared: float
    surface_p99_prepared_to_in: float  # NaN where the input is open
    bounds_error: float
    volume_ratio: float  # prepared / input volume; NaN where the input is open

    @property
    def surface_p99(self) -> float:
        return float(np.nanmax([self.surface_p99_in_to_prepared, self.surface_p99_prepared_to_in]))

    def as_record(self) -> dict:
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else round(float(v), 6)) for k, v in asdict(self).items()}

    def problem(self, metres_per_unit: float | None = None) -> str | None:
        """What makes the prepared solid another shape, in words, or None when it is within tolerance."""
        floor = SURFACE_FLOOR_M / metres_per_unit / self.size if metres_per_unit else 0.0
        if self.bounds_error > MAX_BOUNDS_ERROR:
            return f"prepared bounding box differs from the input's by {100 * self.bounds_error:.1f}% of its size"
        if self.surface_p99 > max(MAX_SURFACE_P99, floor):
            side = ("input surface lost" if self.surface_p99_in_to_prepared >= np.nan_to_num(self.surface_p99_prepared_to_in)
                    else "surface added")  # fmt: skip
            return f"prepared surface is {100 * self.surface_p99:.1f}% of the size away from the input's (p99, {side})"
        if np.isfinite(self.volume_ratio) and abs(self.volume_ratio - 1.0) > MAX_VOLUME_ERROR:
            return f"prepared volume is {100 * self.volume_ratio:.0f}% of the input's"
        return None

    def summary(self) -> str:
        """One line: the three measures in percent."""
        volume = f", volume {100 * self.volume_ratio:.1f}%" if np.isfinite(self.volume_ratio) else ""
        back = f" / {100 * self.surface_p99_prepared_to_in:.2f}%" if np.isfinite(self.surface_p99_prepared_to_in) else ""
        return f"surface p99 {100 * self.surface_p99_in_to_prepared:.2f}%{back}, box {100 * self.bounds_error:.2f}%{volume} of the size"


def _distances(points: np.ndarray, mesh) -> np.ndarray:
    import igl

    return np.sqrt(igl.point_mesh_squared_distance(np.asarray(points, np.float64), np.asarray(mesh.vertices, np.float64),
                                                   np.asarray(mesh.faces, np.int64))[0])  # fmt: skip


def outer_surface_points(soup, count: int, seed: int) -> np.ndarray:
    """Points spread over ``soup``'s surface that have outside on one side (not internal faces or shared cuts)."""
    import trimesh

    points, faces = trimesh.sample.sample_surface(soup, count, seed=seed)
    normals = soup.face_normals[faces]
    probe = SIDE_PROBE * float(soup.extents.max())
    sides = winding_numbers(soup.vertices, soup.faces, np.vstack([points + probe * normals, points - probe * normals]))
    outer = np.minimum(sides[: len(points)], sides[len(points):]) < 0.5
    return points[outer]


def input_volume(bodies: list, seed: int) -> float:
    """The volume the closed ``bodies`` enclose together (overlaps counted once): exact for one body, else estimated."""
    import trimesh

    if len(bodies) == 1:
        return abs(float(bodies[0].volume))
    soup = trimesh.util.concatenate(bodies)
    lo, hi = soup.bounds
    points = np.random.default_rng(seed).uniform(lo, hi, size=(VOLUME_SAMPLES, 3))
    inside = winding_numbers(soup.vertices, soup.faces, points) > 0.5
    return float(inside.mean() * np.prod(hi - lo))


def shape_deviation(bodies: list, prepared, input_is_closed: bool, seed: int = 0) -> ShapeDeviation:
    """How far ``prepared`` is from the input ``bodies`` (the kept bodies of the file, placed as prepared)."""
    import trimesh

    soup = trimesh.util.concatenate(bodies) if len(bodies) > 1 else bodies[0]
    size = float(soup.extents.max())
    outer = outer_surface_points(soup, SAMPLES, seed)
    in_to_prepared = float(np.percentile(_distances(outer, prepared), 99)) / size if len(outer) else float("inf")
    if input_is_closed:
        on_prepared, faces = trimesh.sample.sample_surface(prepared, SAMPLES, seed=seed + 1)
        distance = _distances(on_prepared, soup)
        # a prepared face with the input's solid on both sides is a wall inside the object (the cut faces of
        # touching pieces left in a union): as wrong as one far away. Probed at half the surface tolerance,
        # beyond which a prepared surface may lie from the input's and still pass.
        probe = 0.5 * MAX_SURFACE_P99 * size * prepared.face_normals[faces]
        sides = winding_numbers(soup.vertices, soup.faces, np.vstack([on_prepared + probe, on_prepared - probe]))
        distance[np.minimum(sides[:SAMPLES], sides[SAMPLES:]) > 0.5] = size
        prepared_to_in = float(np.percentile(distance, 99)) / size
        volume_ratio = abs(float(prepared.volume)) / input_volume(bodies, seed)
    else:
        prepared_to_in = volume_ratio = float("nan")
    bounds_error = float(np.abs(soup.bounds - prepared.bounds).max()) / size
    return ShapeDeviation(size, in_to_prepared, prepared_to_in, bounds_error, volume_ratio)


class NotTheInput(ValueError):
    """No route made a solid within tolerance of the input; the message says what changed and why."""

    def __init__(self, message: str, deviation: ShapeDeviation):
        super().__init__(message)
        self.deviation = deviation


def faithful_solid(raw, metres_per_unit: float | None = None, seed: int = 0):
    """The closed solid of the file's mesh ``raw`` that is within tolerance of it, how it was made and its deviation.

    The exact route of ``objects.solidify`` first (repair of one shell, union of closed bodies); when
    its result is not the input (a union that kept the cut faces between touching pieces as walls
    inside, a hole filling that lost part of a scan), the volumetric remesh. Raises ``NotTheInput``
    when neither is within tolerance and ``solidify.SeveralObjects`` for a file holding several objects.
    """
    from dexlite_pipeline.objects.remesh import volumetric_remesh
    from dexlite_pipeline.objects.solidify import VOLUMETRIC, consistently_wound, solid_from_mesh

    solid, record, kept = solid_from_mesh(raw)
    deviation = shape_deviation(kept, solid, record.input_is_closed, seed)
    problem = deviation.problem(metres_per_unit) if solid.is_watertight else "not closed"
    if problem is None:
        return solid, record, deviation
    if record.route != VOLUMETRIC:
        log.info("%s was not the input (%s): remeshing", record.route, problem)
        remeshed = volumetric_remesh([consistently_wound(body) for body in kept], record.input_is_closed)
        remeshed_deviation = shape_deviation(kept, remeshed, record.input_is_closed, seed)
        if remeshed.is_watertight and remeshed_deviation.problem(metres_per_unit) is None:
            record.notes.append(f"the {record.route} was not the input ({problem})")
            record.route = VOLUMETRIC
            return remeshed, record, remeshed_deviation
        remesh_problem = remeshed_deviation.problem(metres_per_unit) if remeshed.is_watertight else "not closed"
        raise NotTheInput(f"prepared solid is not the input: {problem} ({record.summary()}), and the volumetric remesh's "
                          f"{remesh_problem}; nothing is grasped on another shape", remeshed_deviation)  # fmt: skip
    raise NotTheInput(f"prepared solid is not the input: {problem} ({record.summary()}); nothing is grasped on another shape", deviation)
