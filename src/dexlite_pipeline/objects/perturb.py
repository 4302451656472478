"""Seeded perturbations of a generated object: asymmetric scaling, bending, dents, bumps and scan-like surface noise.

A perturbed instance (id ``household-<family>-<NNN>-p<k>``, ``household.py``) is instance NNN of its family changed
by plan k: ``perturbation_plan`` draws the steps from ``numpy.random.default_rng([HOUSEHOLD_SEED, crc32(family), NNN,
PERTURBATION_STREAM, k])`` and the instance's mesh, and ``apply_plan`` applies them, so the id alone rebuilds it.

Every step is a smooth map of space x -> x + d(x) applied to the vertices of the mesh refined to short edges (3.5-6 mm,
by manifold3d, so dents and bends are carried by the surface). Each d is Lipschitz with constant L < 1 (recorded in
the step as ``lipschitz``), so x + d(x) is one-to-one: walls 3 mm thin keep both surfaces apart, the mesh keeps its
connectivity, and the solid stays closed, unbroken and one body. Dents, bumps and noise fade to nothing at the table
(their size times smooth_step(z / h0), h0 = min(half the height, 2 cm)), and scaling and bending keep z = 0 where it
is, so an object rests on the same base as before, at real size. Magnitudes (largest displacement of any point):

- ``scale``: each axis by 0.88-1.12 about the centre of the base (always): ±36 mm at the top of a 30 cm bottle,
  ±12 mm at the rim of a 10 cm mug, ±5 mm across an 8 cm one;
- ``bend``: standing objects (taller than wide) lean, x += s (z / H)^2 along a random horizontal direction, s 3-10 mm
  (at most 20% of the height); lying and flat ones bow in the table's plane, w += s t^2 across their longest horizontal
  axis (t = -1..1 along it), s 3-12 mm (at most 12% of the length); with probability 0.6;
- ``dent`` / ``bump``: a Gaussian push of depth A along the inward / outward surface normal at a random point of the
  upper 80% of the object, width sigma 8-20 mm; A 2-6 mm for dents, 1.5-4 mm for bumps, lowered where needed so that
  L <= 0.6 (about 1 mm on objects under 1 cm thick); 0-2 of each, at least one in all;
- ``noise``: six plane waves along random directions, wavelengths 8-20 mm, amplitudes summing to 0.3-0.6 mm
  (the largest displacement; a scanner's ripple and roughness); with probability 0.7.
"""

from __future__ import annotations

import math

import numpy as np

from dexlite_pipeline.objects.household_shapes import smooth_step

# Seed stream of perturbation plans, beside the family parameters' (family, instance) seeds.
PERTURBATION_STREAM = 0x70E7
# Refinement: edges of the perturbed surface (m), longest extent / 40 within these bounds.
EDGE_BOUNDS_M = (0.0035, 0.006)
# Largest Lipschitz constant a dent or bump may have; the noise's is under 0.9 at every size.
MAX_PUSH_LIPSCHITZ = 0.6
# Documented ranges (m), which the tests hold each step to.
SCALE_RANGE = (0.88, 1.12)
LEAN_RANGE_M, BOW_RANGE_M = (0.003, 0.010), (0.003, 0.012)
DENT_RANGE_M, BUMP_RANGE_M, WIDTH_RANGE_M = (0.002, 0.006), (0.0015, 0.004), (0.008, 0.020)
NOISE_RANGE_M, WAVELENGTH_RANGE_M = (0.0003, 0.0006), (0.008, 0.020)


def refined(mesh, edge: float):
    """``mesh`` with every edge longer than ``edge`` (m) split (manifold3d; vertices kept where they were)."""
    import manifold3d
    import trimesh

    solid = manifold3d.Manifold(manifold3d.Mesh64(vert_properties=np.asarray(mesh.vertices, dtype=np.float64),
                                                  tri_verts=np.asarray(mesh.faces, dtype=np.uint32)))
    out = solid.refine_to_length(edge).to_mesh64()
    return trimesh.Trimesh(np.asarray(out.vert_properties)[:, :3], np.asarray(out.tri_verts), process=False)


def refine_edge(mesh) -> float:
    """The edge length (m) a mesh is refined to before it is perturbed."""
    return float(np.clip(mesh.extents.max() / 40, *EDGE_BOUNDS_M))


def _fade_height(height: float) -> float:
    """h0 (m): dents, bumps and noise grow from zero at the table to full size at this height."""
    return min(0.5 * height, 0.02)


def _push_step(rng, mesh, kind: str) -> dict:
    """A dent or bump: centre on a vertex of the upper 80% whose normal does not face the table."""
    height = float(mesh.bounds[1][2])
    normals = np.asarray(mesh.vertex_normals)
    vertices = np.asarray(mesh.vertices)
    candidates = np.flatnonzero((vertices[:, 2] > 0.2 * height) & (normals[:, 2] > -0.3))
    pick = int(candidates[rng.integers(len(candidates))])
    depth = float(rng.uniform(*(DENT_RANGE_M if kind == "dent" else BUMP_RANGE_M)))
    width = float(rng.uniform(*WIDTH_RANGE_M))
    h0 = _fade_height(height)
    # |grad (A G T)| <= A (max|grad G| + max|T'| max G below h0) = A (e^-1/2 / sigma + pi / (2 h0) G(z = h0))
    below = math.exp(-max(float(vertices[pick, 2]) - h0, 0.0) ** 2 / (2 * width**2))
    per_depth = math.exp(-0.5) / width + math.pi / (2 * h0) * below
    depth = min(depth, MAX_PUSH_LIPSCHITZ / per_depth)
    direction = normals[pick] * (-1.0 if kind == "dent" else 1.0)
    return {"kind": kind, "centre": vertices[pick].tolist(), "direction": (direction / np.linalg.norm(direction)).tolist(),
            "depth": depth, "width": width, "fade": h0, "lipschitz": depth * per_depth, "max_displacement": depth}


def perturbation_plan(rng, mesh) -> list[dict]:
    """The steps (each a dict with ``kind``, its parameters in metres, ``lipschitz`` and ``max_displacement``, m) of
    one perturbation of ``mesh`` (resting on z = 0), drawn from ``rng``; dents and bumps are placed on ``mesh`` as
    refined for perturbation."""
    base = refined(mesh, refine_edge(mesh))
    low, high = base.bounds
    centre = [(low[0] + high[0]) / 2, (low[1] + high[1]) / 2, 0.0]
    factors = rng.uniform(*SCALE_RANGE, size=3)
    half = np.array([high[0] - low[0], high[1] - low[1], 2 * high[2]]) / 2
    steps = [{"kind": "scale", "centre": centre, "factors": factors.tolist(), "lipschitz": float(np.abs(factors - 1).max()),
              "max_displacement": float(np.linalg.norm(np.abs(factors - 1) * half))}]
    scaled = np.asarray(base.vertices) * 1.0
    scaled = apply_step(scaled, steps[0])
    extents = scaled.max(axis=0) - scaled.min(axis=0)
    if rng.uniform() < 0.6:
        if extents[2] >= max(extents[0], extents[1]):
            angle = float(rng.uniform(0.0, 2 * math.pi))
            size = min(float(rng.uniform(*LEAN_RANGE_M)), 0.2 * extents[2])
            steps.append({"kind": "lean", "direction": [math.cos(angle), math.sin(angle), 0.0], "size": size, "height": float(extents[2]),
                          "lipschitz": 2 * size / extents[2], "max_displacement": size})
        else:
            axis = 0 if extents[0] >= extents[1] else 1
            length = float(extents[axis])
            size = min(float(rng.uniform(*BOW_RANGE_M)), 0.12 * length) * float(rng.choice([-1.0, 1.0]))
            middle = float((scaled[:, axis].max() + scaled[:, axis].min()) / 2)
            steps.append({"kind": "bow", "axis": axis, "middle": middle, "length": length, "size": size,
                          "lipschitz": 4 * abs(size) / length, "max_displacement": abs(size)})
    dents, bumps = int(rng.integers(0, 3)), int(rng.integers(0, 3))
    if dents + bumps == 0:
        dents = 1
    for kind in ["dent"] * dents + ["bump"] * bumps:
        steps.append(_push_step(rng, _placed(base, steps), kind))
    if rng.uniform() < 0.7:
        amplitude = float(rng.uniform(*NOISE_RANGE_M))
        directions = rng.normal(size=(6, 3))
        pushes = rng.normal(size=(6, 3))
        wavelengths = rng.uniform(*WAVELENGTH_RANGE_M, size=6)
        h0 = _fade_height(float(extents[2]))
        lipschitz = amplitude / 6 * float((2 * math.pi / wavelengths).sum()) + amplitude * math.pi / (2 * h0)
        steps.append({"kind": "noise", "amplitude": amplitude, "fade": h0,
                      "waves": (directions / np.linalg.norm(directions, axis=1, keepdims=True) * (2 * math.pi / wavelengths)[:, None]).tolist(),
                      "pushes": (pushes / np.linalg.norm(pushes, axis=1, keepdims=True)).tolist(),
                      "phases": rng.uniform(0.0, 2 * math.pi, size=6).tolist(), "lipschitz": lipschitz, "max_displacement": amplitude})
    return steps


def _placed(base, steps: list[dict]):
    """``base`` with ``steps`` applied (the surface later steps are placed on)."""
    import trimesh

    vertices = np.asarray(base.vertices) * 1.0
    for step in steps:
        vertices = apply_step(vertices, step)
    return trimesh.Trimesh(vertices, base.faces, process=False)


def apply_step(vertices: np.ndarray, step: dict) -> np.ndarray:
    """The vertices (m, n x 3) moved by one step of a plan."""
    v = np.array(vertices, dtype=np.float64)
    kind = step["kind"]
    if kind == "scale":
        centre = np.asarray(step["centre"])
        return centre + (v - centre) * np.asarray(step["factors"])
    if kind == "lean":
        return v + np.asarray(step["direction"]) * (step["size"] * (v[:, 2] / step["height"]) ** 2)[:, None]
    if kind == "bow":
        axis = step["axis"]
        t = (v[:, axis] - step["middle"]) / (step["length"] / 2)
        v[:, 1 - axis] += step["size"] * t**2
        return v
    fade = smooth_step(v[:, 2] / step["fade"])
    if kind in ("dent", "bump"):
        gauss = np.exp(-((v - np.asarray(step["centre"])) ** 2).sum(axis=1) / (2 * step["width"] ** 2))
        return v + np.asarray(step["direction"]) * (step["depth"] * gauss * fade)[:, None]
    if kind == "noise":
        waves = np.sin(v @ np.asarray(step["waves"]).T + np.asarray(step["phases"]))  # n x 6, each in [-1, 1]
        return v + (step["amplitude"] / 6) * fade[:, None] * (waves @ np.asarray(step["pushes"]))
    raise ValueError(f"unknown perturbation step {kind!r}")


def apply_plan(mesh, plan: list[dict]):
    """``mesh`` refined (``refine_edge``) and moved by every step of ``plan`` in order (vertex i of the result is vertex i
    of the refined mesh, moved)."""
    return _placed(refined(mesh, refine_edge(mesh)), plan)


def plan_rng(seed: int, family_hash: int, index: int, variant: int):
    """The generator of perturbation ``variant`` (>= 1) of instance ``index`` of a family."""
    return np.random.default_rng([seed, family_hash, index, PERTURBATION_STREAM, variant])
