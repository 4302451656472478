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

``FAMILIES`` holds the original twelve, whose parameters and meshes never change (the dataset rebuilds its
objects from their ids) and which the default round-robin draws. The shape families (plates, pots, pans, kettles,
jugs, handled bottles, bevelled boxes, screwdrivers, knives, spoons, scissors, pliers, apples, pears, bananas,
potatoes, toy figures: ``SHAPE_FAMILIES``) are drawn when ``objects.household_families`` names them; ``ALL_FAMILIES``
is every family an id may name. ``household-<family>-<NNN>-p<k>`` is instance NNN changed by its seeded
perturbation k (dents, bumps, asymmetric scaling, bending, surface noise: ``perturb.py``).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from dexlite_pipeline.objects.household_shapes import (
    HouseholdMeshError,  # re-exported: what a failed build raises
    boolean,
    box_at,
    check_solid,
    cylinder_x,
    handle_torus,
    open_vessel,
    revolve,
    smooth_step,
    uniform,
    vessel_curves,
)
from dexlite_pipeline.objects.kitchen_families import KITCHEN_FAMILIES
from dexlite_pipeline.objects.organic_families import ORGANIC_FAMILIES
from dexlite_pipeline.objects.perturb import apply_plan, perturbation_plan, plan_rng
from dexlite_pipeline.objects.tool_families import TOOL_FAMILIES

HOUSEHOLD_SEED = 20261202
ID_PREFIX = "household"


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


# --------------------------------------------------------------------------- families
# Each family: parameters drawn from a generator (metres), and a builder from those parameters.


def cup_params(rng) -> dict:
    rim = uniform(rng, 0.035, 0.045)
    return {"height": uniform(rng, 0.085, 0.14), "rim_radius": rim, "base_radius": rim * uniform(rng, 0.70, 0.85),
            "wall": uniform(rng, 0.003, 0.005), "base_thickness": uniform(rng, 0.005, 0.008)}


def build_cup(height, rim_radius, base_radius, wall, base_thickness):
    return open_vessel(height, rim_radius, base_radius, wall, base_thickness, roundness=0.0)


def mug_params(rng) -> dict:
    height = uniform(rng, 0.085, 0.11)
    rim = uniform(rng, 0.037, 0.046)
    return {"height": height, "rim_radius": rim, "base_radius": rim * uniform(rng, 0.90, 1.0), "wall": uniform(rng, 0.003, 0.005),
            "base_thickness": uniform(rng, 0.005, 0.008), "handle_span": uniform(rng, 0.045, 0.06),
            "handle_reach": uniform(rng, 0.028, 0.036), "handle_tube_radius": uniform(rng, 0.004, 0.006)}


def build_mug(height, rim_radius, base_radius, wall, base_thickness, handle_span, handle_reach, handle_tube_radius):
    """A cup with a handle: (outer solid ∪ handle torus) − cavity."""
    outer, inner = vessel_curves(height, rim_radius, base_radius, wall, base_thickness, roundness=0.0)
    solid = revolve(np.vstack([[0.0, 0.0], outer, [0.0, height]]))
    cavity = revolve(np.vstack([[0.0, base_thickness], inner, [0.0, inner[-1, 1]]]))
    centre_z = height * 0.55
    top = centre_z + handle_span / 2
    if top + handle_tube_radius > height - 0.004:
        centre_z -= top + handle_tube_radius - (height - 0.004)
    attach = float(np.interp(centre_z, outer[:, 1], outer[:, 0]))
    handle = handle_torus(attach, centre_z, handle_span, handle_reach, handle_tube_radius)
    return boolean("difference", [boolean("union", [solid, handle]), cavity])


def bowl_params(rng) -> dict:
    rim = uniform(rng, 0.06, 0.095)
    return {"height": rim * uniform(rng, 0.55, 0.8), "rim_radius": rim, "base_radius": rim * uniform(rng, 0.35, 0.5),
            "wall": uniform(rng, 0.003, 0.005), "base_thickness": uniform(rng, 0.005, 0.008), "roundness": uniform(rng, 0.6, 1.0)}


def build_bowl(height, rim_radius, base_radius, wall, base_thickness, roundness):
    return open_vessel(height, rim_radius, base_radius, wall, base_thickness, roundness)


def _bottle_profile(height, radius, neck_radius, body_fraction, shoulder_fraction, top_radius, top_height, waist):
    """Closed profile of a bottle: chamfered foot, body (optionally waisted), cosine shoulder, neck, cap or lip."""
    body_top = height * body_fraction
    shoulder_top = body_top + height * shoulder_fraction
    z_body = np.linspace(0.004, body_top, 24)
    r_body = radius - waist * np.sin(math.pi * (z_body - 0.004) / (body_top - 0.004)) ** 2
    z_shoulder = np.linspace(body_top, shoulder_top, 16)[1:]
    r_shoulder = radius + (neck_radius - radius) * smooth_step((z_shoulder - body_top) / (shoulder_top - body_top))
    cap_bottom = height - top_height
    return np.vstack([
        [[0.0, 0.0], [radius - 0.004, 0.0]],
        np.stack([r_body, z_body], axis=1),
        np.stack([r_shoulder, z_shoulder], axis=1),
        [[neck_radius, cap_bottom], [top_radius, cap_bottom], [top_radius, height], [0.0, height]],
    ])


def bottle_params(rng) -> dict:
    neck = uniform(rng, 0.011, 0.014)
    return {"height": uniform(rng, 0.19, 0.26), "radius": uniform(rng, 0.03, 0.037), "neck_radius": neck,
            "body_fraction": uniform(rng, 0.55, 0.7), "shoulder_fraction": uniform(rng, 0.12, 0.2),
            "top_radius": neck + uniform(rng, 0.002, 0.004), "top_height": uniform(rng, 0.015, 0.022), "waist": uniform(rng, 0.0, 0.004)}


def build_bottle(**params):
    return revolve(_bottle_profile(**params))


def wine_bottle_params(rng) -> dict:
    neck = uniform(rng, 0.0125, 0.0145)
    return {"height": uniform(rng, 0.29, 0.31), "radius": uniform(rng, 0.036, 0.039), "neck_radius": neck,
            "body_fraction": uniform(rng, 0.58, 0.64), "shoulder_fraction": uniform(rng, 0.08, 0.12),
            "top_radius": neck + uniform(rng, 0.0012, 0.002), "top_height": uniform(rng, 0.008, 0.012), "waist": 0.0}


def build_wine_bottle(**params):
    return revolve(_bottle_profile(**params))


def can_params(rng) -> dict:
    return {"height": uniform(rng, 0.095, 0.125), "radius": uniform(rng, 0.026, 0.034)}


def build_can(height, radius):
    """A drinks can: chamfered foot, straight body, tapered neck to a rim 5 mm inside the body."""
    profile = [[0.0, 0.0], [radius - 0.005, 0.0], [radius, 0.007], [radius, height - 0.012],
               [radius - 0.005, height - 0.003], [radius - 0.005, height], [0.0, height]]
    return revolve(profile)


def jar_params(rng) -> dict:
    radius = uniform(rng, 0.03, 0.05)
    return {"height": uniform(rng, 0.075, 0.14), "radius": radius, "neck_radius": radius * uniform(rng, 0.8, 0.9),
            "lid_height": uniform(rng, 0.012, 0.02)}


def build_jar(height, radius, neck_radius, lid_height):
    """A jar: rounded foot, straight body, rounded shoulder to a neck, a lid slightly wider than the neck."""
    lid_bottom = height - lid_height
    shoulder_top = lid_bottom - 0.003
    shoulder = min(0.015, 0.3 * shoulder_top)
    z_shoulder = np.linspace(shoulder_top - shoulder, shoulder_top, 12)
    r_shoulder = radius + (neck_radius - radius) * np.sin(0.5 * math.pi * (z_shoulder - z_shoulder[0]) / shoulder) ** 2
    lid = neck_radius + 0.003
    return revolve(np.vstack([
        [[0.0, 0.0], [radius - 0.003, 0.0], [radius, 0.003]],
        np.stack([r_shoulder, z_shoulder], axis=1),
        [[neck_radius, lid_bottom], [lid, lid_bottom], [lid, height], [0.0, height]],
    ]))


def cereal_box_params(rng) -> dict:
    return {"height": uniform(rng, 0.28, 0.32), "width": uniform(rng, 0.19, 0.22), "depth": uniform(rng, 0.06, 0.08)}


def build_box(height, width, depth):
    """An upright box: width along x, depth along y, height along z."""
    return box_at([width, depth, height], [0.0, 0.0, height / 2])


def box_params(rng) -> dict:
    return {"height": uniform(rng, 0.10, 0.22), "width": uniform(rng, 0.06, 0.16), "depth": uniform(rng, 0.035, 0.08)}


def milk_carton_params(rng) -> dict:
    return {"side": uniform(rng, 0.065, 0.095), "body_height": uniform(rng, 0.15, 0.2), "gable_height": uniform(rng, 0.02, 0.03),
            "fin_height": uniform(rng, 0.008, 0.012)}


def build_milk_carton(side, body_height, gable_height, fin_height):
    """A gable-top carton: a square prism with a roof ridge along y, and the sealed fin on the ridge (3 mm thick)."""
    import trimesh

    half = side / 2
    corners = [[x, y, z] for x in (-half, half) for y in (-half, half) for z in (0.0, body_height)]
    ridge = [[0.0, y, body_height + gable_height] for y in (-half, half)]
    body = trimesh.convex.convex_hull(np.array(corners + ridge))
    fin = box_at([0.003, side, fin_height + 0.004], [0.0, 0.0, body_height + gable_height + fin_height / 2 - 0.002])
    return boolean("union", [body, fin])


def hammer_params(rng) -> dict:
    return {"handle_length": uniform(rng, 0.25, 0.31), "handle_radius": uniform(rng, 0.012, 0.016),
            "head_length": uniform(rng, 0.10, 0.13), "head_section": uniform(rng, 0.024, 0.032)}


def build_hammer(handle_length, handle_radius, head_length, head_section):
    """A hammer lying on its side: handle along x, the head across it (along y) at the +x end."""
    lift = max(handle_radius, head_section / 2)
    handle = cylinder_x(handle_radius, handle_length, [handle_length / 2, 0.0, lift])
    head = box_at([head_section, head_length, head_section], [handle_length - head_section / 2 + 0.005, 0.0, lift])
    return boolean("union", [handle, head])


def spatula_params(rng) -> dict:
    return {"handle_length": uniform(rng, 0.16, 0.21), "handle_radius": uniform(rng, 0.009, 0.013),
            "blade_length": uniform(rng, 0.08, 0.11), "blade_width": uniform(rng, 0.06, 0.085), "blade_thickness": uniform(rng, 0.004, 0.006)}


def build_spatula(handle_length, handle_radius, blade_length, blade_width, blade_thickness):
    """A spatula lying flat: handle along x resting on the table, a flat blade beyond it, overlapping by 1.5 cm."""
    handle = cylinder_x(handle_radius, handle_length, [handle_length / 2, 0.0, handle_radius])
    start = handle_length - 0.015
    blade = box_at([blade_length, blade_width, blade_thickness], [start + blade_length / 2, 0.0, blade_thickness / 2])
    return boolean("union", [handle, blade])


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


# The shape families (objects/kitchen_families.py, tool_families.py, organic_families.py), in their round-robin order:
# drawn for training only when ``objects.household_families`` names them, so the default order is the twelve above.
SHAPE_FAMILIES: dict[str, tuple] = {**KITCHEN_FAMILIES, **TOOL_FAMILIES, **ORGANIC_FAMILIES}
# Every family an id may name.
ALL_FAMILIES: dict[str, tuple] = {**FAMILIES, **SHAPE_FAMILIES}


# --------------------------------------------------------------------------- ids and checks


class HouseholdId(NamedTuple):
    """What an id names: instance ``index`` of ``family``, and its perturbation ``variant`` (0: as generated)."""

    family: str
    index: int
    variant: int = 0


def household_id(family: str, index: int, variant: int = 0) -> str:
    """``household-<family>-<NNN>``, with ``-p<variant>`` for a perturbed instance (variant >= 1)."""
    return f"{ID_PREFIX}-{family}-{index:03d}" + (f"-p{variant}" if variant else "")


def parse_household_id(object_id: str) -> HouseholdId:
    """(family, instance number, perturbation variant) of ``household-<family>-<NNN>`` (variant 0) or
    ``household-<family>-<NNN>-p<k>`` (k >= 1); ValueError naming the id otherwise. ``[0]`` is the family."""
    prefix, _, rest = object_id.partition("-")
    variant = 0
    head, _, tail = rest.rpartition("-")
    if tail.startswith("p") and tail[1:].isdigit() and not tail[1:].startswith("0"):
        rest, variant = head, int(tail[1:])
    family, _, number = rest.rpartition("-")
    if prefix != ID_PREFIX or family not in ALL_FAMILIES or not number.isdigit():
        raise ValueError(f"{object_id!r}: not a household object id (household-<family>-<NNN>[-p<k>], families: {', '.join(ALL_FAMILIES)})")
    return HouseholdId(family, int(number), variant)


def base_household_id(object_id: str) -> str:
    """The id of the instance a (perturbed) household id is made from: ``household-mug-040-p1`` -> ``household-mug-040``."""
    family, index, _ = parse_household_id(object_id)
    return household_id(family, index)


def build_family(family: str, params: dict):
    """The checked mesh (metres) of one family instance from explicit parameters."""
    if family not in ALL_FAMILIES:
        raise ValueError(f"unknown household family {family!r} (families: {', '.join(ALL_FAMILIES)})")
    return _finished(ALL_FAMILIES[family][1](**params), family)


def _finished(mesh, name: str):
    """``mesh`` with its lowest point exactly on z = 0 (booleans leave rounding noise), checked by ``check_solid``."""
    mesh.apply_translation([0.0, 0.0, -mesh.bounds[0][2]])
    check_solid(mesh, name)
    return mesh


def family_params(family: str, index: int) -> dict:
    """The seeded parameters (metres) of instance ``index`` of ``family``."""
    rng = np.random.default_rng([HOUSEHOLD_SEED, zlib.crc32(family.encode()), index])
    return ALL_FAMILIES[family][0](rng)


def household_object(object_id: str) -> HouseholdObject:
    """The object an id names (same parameters and mesh every time). A perturbed id's ``params`` hold the instance's
    parameters and, under ``"perturbation"``, the steps applied (``perturb.perturbation_plan``)."""
    family, index, variant = parse_household_id(object_id)
    params = family_params(family, index)
    mesh = _finished(ALL_FAMILIES[family][1](**params), object_id)
    if variant:
        plan = perturbation_plan(plan_rng(HOUSEHOLD_SEED, zlib.crc32(family.encode()), index, variant), mesh)
        mesh = _finished(apply_plan(mesh, plan), object_id)
        params = {**params, "perturbation": plan}
    return HouseholdObject(object_id, family, index, params, mesh)


def training_household_ids(count: int, excluded: frozenset[str] = frozenset(), families: tuple[str, ...] = (),
                           variants: tuple[int, ...] = (0,)) -> list[str]:
    """The first ``count`` ids in round-robin family order (instance 0 of each family, then 1, ...), skipping ``excluded``
    and every id whose instance (``base_household_id``) is excluded.

    ``families``: only these families, in the order given (empty: the twelve of ``FAMILIES``, in its order), so a
    campaign batch can grow the families that have the fewest grasps without changing any object's id.
    ``variants``: of each instance, these perturbation variants in this order (0: the instance as generated), so
    ``(0, 1)`` draws every instance and then its first perturbed variant, ``(1,)`` perturbed variants only.
    """
    chosen = tuple(families) or tuple(FAMILIES)
    unknown = [f for f in chosen if f not in ALL_FAMILIES]
    if unknown:
        raise ValueError(f"unknown household families {', '.join(map(repr, unknown))} (families: {', '.join(ALL_FAMILIES)})")
    if not variants or any(v < 0 for v in variants) or len(set(variants)) != len(variants):
        raise ValueError(f"perturbation variants must be distinct numbers >= 0 (0: as generated), not {list(variants)}")
    ids: list[str] = []
    index = 0
    while len(ids) < count:
        drawn = [(household_id(f, index, v), household_id(f, index)) for f in chosen for v in variants]
        ids += [i for i, base in drawn if i not in excluded and base not in excluded][: count - len(ids)]
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
