"""Household objects made by the project: seeded families of cups, mugs, bowls, bottles, cans,
jars, boxes, cartons and tools, at their real size, in metres.

Every mesh is a closed, single, positive-volume solid standing in its resting pose: +z up,
the base on z = 0, vessels and bottles revolved about the z axis, tools lying on the table
with their long axis along x. (``prepare_objects`` centres a mesh on its bounding box and
keeps its orientation, and the stability test stands it in that orientation.)

An instance is named ``household-<family>-<NNN>``; its parameters are drawn from
``numpy.random.default_rng([HOUSEHOLD_SEED, crc32(family), NNN])``, so an id always means the
same object. Ranges (metres) follow common real objects: walls of cups, mugs and bowls 3-5 mm,
a mug handle 8-12 mm thick with room for two or three fingers, a wine bottle 29-31 cm tall, a
cereal box about 30 x 20 x 7 cm, a one-litre-class milk carton.

Vessels are revolved profiles (``trimesh.creation.revolve``): the wall's inner curve is the
outer one offset by the wall thickness along its normal. A mug is (outer solid ∪ handle) −
cavity, the handle a torus in the xz plane (manifold3d booleans), so the handle's ends are cut
flush with the inside of the wall whatever the wall thickness.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HOUSEHOLD_SEED = 20261202
ID_PREFIX = "household"
# Angular resolution of revolved surfaces: chord error under 0.15 mm at a 10 cm radius.
REVOLVE_SECTIONS = 64
# Profile points closer than this (m) to a neighbour are one point.
MIN_SPACING = 1e-5


class HouseholdMeshError(ValueError):
    """A generated mesh that is not a closed single solid (a bug in a family's parameters)."""


@dataclass(frozen=True)
class HouseholdObject:
    """One generated object: its id, family, instance number, parameters (metres) and mesh (metres)."""

    object_id: str
    family: str
    index: int
    params: dict
    mesh: object  # trimesh.Trimesh

    @property
    def real_radius_m(self) -> float:
        """Largest vertex distance from the bounding-box centre (m): the radius ``prepare_objects`` normalizes away."""
        return real_radius_m(self.mesh)


def real_radius_m(mesh) -> float:
    """Largest vertex distance from the bounding-box centre, in the mesh's units."""
    centre = (mesh.bounds[0] + mesh.bounds[1]) / 2
    return float(np.linalg.norm(np.asarray(mesh.vertices) - centre, axis=1).max())


# --------------------------------------------------------------------------- geometry helpers


def _revolve(profile) -> object:
    """Solid of revolution about z of an (r, z) profile that starts and ends on the axis (outward normals either way)."""
    import trimesh

    profile = np.asarray(profile, dtype=np.float64)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(profile, axis=0), axis=1) > MIN_SPACING])
    mesh = trimesh.creation.revolve(profile[keep], sections=REVOLVE_SECTIONS)
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def _offset_inward(curve: np.ndarray, distance: float) -> np.ndarray:
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


def _clip_z(curve: np.ndarray, z_min: float, z_max: float) -> np.ndarray:
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


def _wall_curve(base_radius: float, rim_radius: float, height: float, roundness: float, n: int = 32) -> np.ndarray:
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


def _vessel_curves(height, rim_radius, base_radius, wall, base_thickness, roundness):
    """(outer wall from z = 0 to the rim, inner wall from the cavity floor to 1 cm above the rim), (r, z) polylines."""
    outer = _wall_curve(base_radius, rim_radius, height, roundness)
    inner = _clip_z(_offset_inward(outer, wall), base_thickness, height + 0.01)
    return _clip_z(outer, 0.0, height), inner


def _open_vessel(height, rim_radius, base_radius, wall, base_thickness, roundness):
    """A cup or bowl: one revolve of its wall section (outer wall up, flat rim, inner wall down, cavity floor)."""
    outer, inner = _vessel_curves(height, rim_radius, base_radius, wall, base_thickness, roundness)
    inner = _clip_z(inner, base_thickness, height)
    return _revolve(np.vstack([[0.0, 0.0], outer, inner[::-1], [0.0, base_thickness]]))


def _boolean(kind: str, meshes):
    import trimesh

    operation = {"union": trimesh.boolean.union, "difference": trimesh.boolean.difference}[kind]
    return operation(meshes, engine="manifold")


def _handle_torus(attach_radius, centre_z, span, reach, tube_radius):
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


def _box(extents, centre) -> object:
    import trimesh

    box = trimesh.creation.box(extents=extents)
    box.apply_translation(centre)
    return box


def _cylinder_x(radius, length, centre) -> object:
    """A cylinder along x."""
    import trimesh

    cylinder = trimesh.creation.cylinder(radius=radius, height=length, sections=32)
    cylinder.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0]))
    cylinder.apply_translation(centre)
    return cylinder


def _smooth_step(t):
    t = np.clip(t, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(math.pi * t)


# --------------------------------------------------------------------------- families
# Each family: parameters drawn from a generator (metres), and a builder from those parameters.


def _u(rng, low, high) -> float:
    return float(rng.uniform(low, high))


def cup_params(rng) -> dict:
    rim = _u(rng, 0.035, 0.045)
    return {"height": _u(rng, 0.085, 0.14), "rim_radius": rim, "base_radius": rim * _u(rng, 0.70, 0.85),
            "wall": _u(rng, 0.003, 0.005), "base_thickness": _u(rng, 0.005, 0.008)}


def build_cup(height, rim_radius, base_radius, wall, base_thickness):
    return _open_vessel(height, rim_radius, base_radius, wall, base_thickness, roundness=0.0)


def mug_params(rng) -> dict:
    height = _u(rng, 0.085, 0.11)
    rim = _u(rng, 0.037, 0.046)
    return {"height": height, "rim_radius": rim, "base_radius": rim * _u(rng, 0.90, 1.0), "wall": _u(rng, 0.003, 0.005),
            "base_thickness": _u(rng, 0.005, 0.008), "handle_span": _u(rng, 0.045, 0.06),
            "handle_reach": _u(rng, 0.028, 0.036), "handle_tube_radius": _u(rng, 0.004, 0.006)}


def build_mug(height, rim_radius, base_radius, wall, base_thickness, handle_span, handle_reach, handle_tube_radius):
    """A cup with a handle: (outer solid ∪ handle torus) − cavity."""
    outer, inner = _vessel_curves(height, rim_radius, base_radius, wall, base_thickness, roundness=0.0)
    solid = _revolve(np.vstack([[0.0, 0.0], outer, [0.0, height]]))
    cavity = _revolve(np.vstack([[0.0, base_thickness], inner, [0.0, inner[-1, 1]]]))
    centre_z = height * 0.55
    top = centre_z + handle_span / 2
    if top + handle_tube_radius > height - 0.004:
        centre_z -= top + handle_tube_radius - (height - 0.004)
    attach = float(np.interp(centre_z, outer[:, 1], outer[:, 0]))
    handle = _handle_torus(attach, centre_z, handle_span, handle_reach, handle_tube_radius)
    return _boolean("difference", [_boolean("union", [solid, handle]), cavity])


def bowl_params(rng) -> dict:
    rim = _u(rng, 0.06, 0.095)
    return {"height": rim * _u(rng, 0.55, 0.8), "rim_radius": rim, "base_radius": rim * _u(rng, 0.35, 0.5),
            "wall": _u(rng, 0.003, 0.005), "base_thickness": _u(rng, 0.005, 0.008), "roundness": _u(rng, 0.6, 1.0)}


def build_bowl(height, rim_radius, base_radius, wall, base_thickness, roundness):
    return _open_vessel(height, rim_radius, base_radius, wall, base_thickness, roundness)


def _bottle_profile(height, radius, neck_radius, body_fraction, shoulder_fraction, top_radius, top_height, waist):
    """Closed profile of a bottle: chamfered foot, body (optionally waisted), cosine shoulder, neck, cap or lip."""
    body_top = height * body_fraction
    shoulder_top = body_top + height * shoulder_fraction
    z_body = np.linspace(0.004, body_top, 24)
    r_body = radius - waist * np.sin(math.pi * (z_body - 0.004) / (body_top - 0.004)) ** 2
    z_shoulder = np.linspace(body_top, shoulder_top, 16)[1:]
    r_shoulder = radius + (neck_radius - radius) * _smooth_step((z_shoulder - body_top) / (shoulder_top - body_top))
    cap_bottom = height - top_height
    return np.vstack([
        [[0.0, 0.0], [radius - 0.004, 0.0]],
        np.stack([r_body, z_body], axis=1),
        np.stack([r_shoulder, z_shoulder], axis=1),
        [[neck_radius, cap_bottom], [top_radius, cap_bottom], [top_radius, height], [0.0, height]],
    ])


def bottle_params(rng) -> dict:
    neck = _u(rng, 0.011, 0.014)
    return {"height": _u(rng, 0.19, 0.26), "radius": _u(rng, 0.03, 0.037), "neck_radius": neck,
            "body_fraction": _u(rng, 0.55, 0.7), "shoulder_fraction": _u(rng, 0.12, 0.2),
            "top_radius": neck + _u(rng, 0.002, 0.004), "top_height": _u(rng, 0.015, 0.022), "waist": _u(rng, 0.0, 0.004)}


def build_bottle(**params):
    return _revolve(_bottle_profile(**params))


def wine_bottle_params(rng) -> dict:
    neck = _u(rng, 0.0125, 0.0145)
    return {"height": _u(rng, 0.29, 0.31), "radius": _u(rng, 0.036, 0.039), "neck_radius": neck,
            "body_fraction": _u(rng, 0.58, 0.64), "shoulder_fraction": _u(rng, 0.08, 0.12),
            "top_radius": neck + _u(rng, 0.0012, 0.002), "top_height": _u(rng, 0.008, 0.012), "waist": 0.0}


def build_wine_bottle(**params):
    return _revolve(_bottle_profile(**params))


def can_params(rng) -> dict:
    return {"height": _u(rng, 0.095, 0.125), "radius": _u(rng, 0.026, 0.034)}


def build_can(height, radius):
    """A drinks can: chamfered foot, straight body, tapered neck to a rim 5 mm inside the body."""
    profile = [[0.0, 0.0], [radius - 0.005, 0.0], [radius, 0.007], [radius, height - 0.012],
               [radius - 0.005, height - 0.003], [radius - 0.005, height], [0.0, height]]
    return _revolve(profile)


def jar_params(rng) -> dict:
    radius = _u(rng, 0.03, 0.05)
    return {"height": _u(rng, 0.075, 0.14), "radius": radius, "neck_radius": radius * _u(rng, 0.8, 0.9),
            "lid_height": _u(rng, 0.012, 0.02)}


def build_jar(height, radius, neck_radius, lid_height):
    """A jar: rounded foot, straight body, rounded shoulder to a neck, a lid slightly wider than the neck."""
    lid_bottom = height - lid_height
    shoulder_top = lid_bottom - 0.003
    shoulder = min(0.015, 0.3 * shoulder_top)
    z_shoulder = np.linspace(shoulder_top - shoulder, shoulder_top, 12)
    r_shoulder = radius + (neck_radius - radius) * np.sin(0.5 * math.pi * (z_shoulder - z_shoulder[0]) / shoulder) ** 2
    lid = neck_radius + 0.003
    return _revolve(np.vstack([
        [[0.0, 0.0], [radius - 0.003, 0.0], [radius, 0.003]],
        np.stack([r_shoulder, z_shoulder], axis=1),
        [[neck_radius, lid_bottom], [lid, lid_bottom], [lid, height], [0.0, height]],
    ]))


def cereal_box_params(rng) -> dict:
    return {"height": _u(rng, 0.28, 0.32), "width": _u(rng, 0.19, 0.22), "depth": _u(rng, 0.06, 0.08)}


def build_box(height, width, depth):
    """An upright box: width along x, depth along y, height along z."""
    return _box([width, depth, height], [0.0, 0.0, height / 2])


def box_params(rng) -> dict:
    return {"height": _u(rng, 0.10, 0.22), "width": _u(rng, 0.06, 0.16), "depth": _u(rng, 0.035, 0.08)}


def milk_carton_params(rng) -> dict:
    return {"side": _u(rng, 0.065, 0.095), "body_height": _u(rng, 0.15, 0.2), "gable_height": _u(rng, 0.02, 0.03),
            "fin_height": _u(rng, 0.008, 0.012)}


def build_milk_carton(side, body_height, gable_height, fin_height):
    """A gable-top carton: a square prism with a roof ridge along y, and the sealed fin on the ridge (3 mm thick)."""
    import trimesh

    half = side / 2
    corners = [[x, y, z] for x in (-half, half) for y in (-half, half) for z in (0.0, body_height)]
    ridge = [[0.0, y, body_height + gable_height] for y in (-half, half)]
    body = trimesh.convex.convex_hull(np.array(corners + ridge))
    fin = _box([0.003, side, fin_height + 0.004], [0.0, 0.0, body_height + gable_height + fin_height / 2 - 0.002])
    return _boolean("union", [body, fin])


def hammer_params(rng) -> dict:
    return {"handle_length": _u(rng, 0.25, 0.31), "handle_radius": _u(rng, 0.012, 0.016),
            "head_length": _u(rng, 0.10, 0.13), "head_section": _u(rng, 0.024, 0.032)}


def build_hammer(handle_length, handle_radius, head_length, head_section):
    """A hammer lying on its side: handle along x, the head across it (along y) at the +x end."""
    lift = max(handle_radius, head_section / 2)
    handle = _cylinder_x(handle_radius, handle_length, [handle_length / 2, 0.0, lift])
    head = _box([head_section, head_length, head_section], [handle_length - head_section / 2 + 0.005, 0.0, lift])
    return _boolean("union", [handle, head])


def spatula_params(rng) -> dict:
    return {"handle_length": _u(rng, 0.16, 0.21), "handle_radius": _u(rng, 0.009, 0.013),
            "blade_length": _u(rng, 0.08, 0.11), "blade_width": _u(rng, 0.06, 0.085), "blade_thickness": _u(rng, 0.004, 0.006)}


def build_spatula(handle_length, handle_radius, blade_length, blade_width, blade_thickness):
    """A spatula lying flat: handle along x resting on the table, a flat blade beyond it, overlapping by 1.5 cm."""
    handle = _cylinder_x(handle_radius, handle_length, [handle_length / 2, 0.0, handle_radius])
    start = handle_length - 0.015
    blade = _box([blade_length, blade_width, blade_thickness], [start + blade_length / 2, 0.0, blade_thickness / 2])
    return _boolean("union", [handle, blade])


# family name -> (parameter draw, builder); the order is the round-robin order of household_count.
FAMILIES: dict[str, tuple] = {
    "mug": (mug_params, build_mug),
    "bowl": (bowl_params, build_bowl),
    "bottle": (bottle_params, build_bottle),
    "cereal_box": (cereal_box_params, build_box),
    "cup": (cup_params, build_cup),
    "can": (can_params, build_can),
    "wine_bottle": (wine_bottle_params, build_wine_bottle),
    "milk_carton": (milk_carton_params, build_milk_carton),
    "jar": (jar_params, build_jar),
    "box": (box_params, build_box),
    "hammer": (hammer_params, build_hammer),
    "spatula": (spatula_params, build_spatula),
}


# --------------------------------------------------------------------------- ids and checks


def household_id(family: str, index: int) -> str:
    return f"{ID_PREFIX}-{family}-{index:03d}"


def parse_household_id(object_id: str) -> tuple[str, int]:
    """(family, instance number) of ``household-<family>-<NNN>``; ValueError naming the id otherwise."""
    prefix, _, rest = object_id.partition("-")
    family, _, number = rest.rpartition("-")
    if prefix != ID_PREFIX or family not in FAMILIES or not number.isdigit():
        raise ValueError(f"{object_id!r}: not a household object id (household-<family>-<NNN>, families: {', '.join(FAMILIES)})")
    return family, int(number)


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


def build_family(family: str, params: dict):
    """The checked mesh (metres) of one family instance from explicit parameters."""
    if family not in FAMILIES:
        raise ValueError(f"unknown household family {family!r} (families: {', '.join(FAMILIES)})")
    return _finished(FAMILIES[family][1](**params), family)


def _finished(mesh, name: str):
    """``mesh`` with its lowest point exactly on z = 0 (booleans leave rounding noise), checked by ``check_solid``."""
    mesh.apply_translation([0.0, 0.0, -mesh.bounds[0][2]])
    check_solid(mesh, name)
    return mesh


def family_params(family: str, index: int) -> dict:
    """The seeded parameters (metres) of instance ``index`` of ``family``."""
    rng = np.random.default_rng([HOUSEHOLD_SEED, zlib.crc32(family.encode()), index])
    return FAMILIES[family][0](rng)


def household_object(object_id: str) -> HouseholdObject:
    """The object an id names (same parameters and mesh every time)."""
    family, index = parse_household_id(object_id)
    params = family_params(family, index)
    return HouseholdObject(object_id, family, index, params, _finished(FAMILIES[family][1](**params), object_id))


def training_household_ids(count: int, excluded: frozenset[str] = frozenset(), families: tuple[str, ...] = ()) -> list[str]:
    """The first ``count`` ids in round-robin family order (instance 0 of each family, then 1, ...), skipping ``excluded``.

    ``families``: only these families, in the order given (empty: every family of ``FAMILIES``, in its order), so a
    campaign batch can grow the families that have the fewest grasps without changing any object's id.
    """
    chosen = tuple(families) or tuple(FAMILIES)
    unknown = [f for f in chosen if f not in FAMILIES]
    if unknown:
        raise ValueError(f"unknown household families {', '.join(map(repr, unknown))} (families: {', '.join(FAMILIES)})")
    ids: list[str] = []
    index = 0
    while len(ids) < count:
        ids += [i for i in (household_id(f, index) for f in chosen) if i not in excluded][: count - len(ids)]
        index += 1
    return ids


def write_mesh_obj(mesh, path: Path) -> None:
    """Write ``mesh`` as .obj atomically, leaving an identical existing file untouched (its time stamp too)."""
    from dexlite_pipeline.atomic import atomic_path

    text = mesh.export(file_type="obj")
    if path.is_file() and path.read_text() == text:
        return
    with atomic_path(path) as tmp:
        tmp.write_text(text)


# --------------------------------------------------------------------------- the check meshes
# Fixed instances in no split, for `dexlite grasp` checks (benchmarks/experiments/make_household_meshes.py).

CHECK_OBJECTS: dict[str, tuple[str, dict]] = {
    "mug": ("mug", {"height": 0.095, "rim_radius": 0.041, "base_radius": 0.039, "wall": 0.004, "base_thickness": 0.006,
                    "handle_span": 0.052, "handle_reach": 0.032, "handle_tube_radius": 0.005}),
    "bowl": ("bowl", {"height": 0.06, "rim_radius": 0.08, "base_radius": 0.035, "wall": 0.004, "base_thickness": 0.006,
                      "roundness": 0.85}),
    "wine_bottle": ("wine_bottle", {"height": 0.30, "radius": 0.0375, "neck_radius": 0.0135, "body_fraction": 0.6,
                                    "shoulder_fraction": 0.1, "top_radius": 0.015, "top_height": 0.01, "waist": 0.0}),
    "cereal_box": ("cereal_box", {"height": 0.30, "width": 0.20, "depth": 0.07}),
}


def check_meshes() -> dict[str, object]:
    """The check meshes by name (metres): a mug with a 4 mm wall and a handle, a bowl, a 30 cm wine bottle, a cereal box."""
    return {name: build_family(family, params) for name, (family, params) in CHECK_OBJECTS.items()}
