"""Hand-tool and cutlery shape families: screwdrivers, knives, spoons, scissors (closed) and pliers.

Like the original hammer and spatula (``household.py``): seeded parameters in metres at real size, each object one
closed solid lying on the table in its resting pose (+z up, lowest point on z = 0, long axis along x), built from
revolved profiles, convex hulls and capsules joined with manifold3d booleans.
"""

from __future__ import annotations

import math

import numpy as np

from dexlite_pipeline.objects.household_shapes import boolean, hull, revolve, rod_between, rounded_box, uniform


def _circle(centre_xy, radius: float, z_values, count: int = 16) -> np.ndarray:
    """Points of a horizontal circle (m) repeated at each height of ``z_values``: prisms for hulls."""
    angles = np.linspace(0.0, 2 * math.pi, count, endpoint=False)
    ring = np.stack([centre_xy[0] + radius * np.cos(angles), centre_xy[1] + radius * np.sin(angles)], axis=1)
    return np.vstack([np.column_stack([ring, np.full(count, z)]) for z in z_values])


def screwdriver_params(rng) -> dict:
    """Flat screwdrivers: a hexagonal handle 8-12 cm long and 21-31 mm across its flats, a shaft 6-15 cm long and
    5-8 mm thick ending in a flattened blade."""
    return {"handle_length": uniform(rng, 0.08, 0.12), "handle_radius": uniform(rng, 0.012, 0.018),
            "shaft_length": uniform(rng, 0.06, 0.15), "shaft_radius": uniform(rng, 0.0025, 0.004)}


def build_screwdriver(handle_length, handle_radius, shaft_length, shaft_radius):
    """A screwdriver lying on a flat of its six-sided handle (handle from x = 0 along +x, then the shaft and blade)."""
    import trimesh

    r, length = handle_radius, handle_length
    profile = [[0.0, 0.0], [0.7 * r, 0.0], [r, 0.012], [r, length - 0.02], [0.75 * r, length - 0.008], [0.55 * r, length], [0.0, length]]
    handle = revolve(profile, sections=6)
    # Turn the hexagon so a flat faces local +x, which the quarter turn about y below sends to -z: it rests on a flat.
    handle.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 6, [0.0, 0.0, 1.0]))
    handle.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [0.0, 1.0, 0.0]))
    axis_z = r * math.cos(math.pi / 6)
    handle.apply_translation([0.0, 0.0, axis_z])
    tip = length + shaft_length
    shaft = rod_between([length - 0.005, 0.0, axis_z], [tip - 0.01, 0.0, axis_z], shaft_radius, rounded=False)
    blade = hull(np.vstack([_circle((0.0, 0.0), shaft_radius, [0.0])[:, [2, 0, 1]] + [tip - 0.012, 0.0, axis_z],
                            [[tip, y, axis_z + z] for y in (-1.1 * shaft_radius, 1.1 * shaft_radius) for z in (-0.3 * shaft_radius, 0.3 * shaft_radius)]]))
    return boolean("union", [handle, shaft, blade])


def knife_params(rng) -> dict:
    """Kitchen and table knives: handle 10-13 cm long, 22-28 mm wide, 14-20 mm thick; blade 12-20 cm long, 2.5-4.5 cm
    wide, 1.5-2.5 mm thick."""
    return {"handle_length": uniform(rng, 0.10, 0.13), "handle_width": uniform(rng, 0.022, 0.028),
            "handle_thickness": uniform(rng, 0.014, 0.02), "blade_length": uniform(rng, 0.12, 0.20),
            "blade_width": uniform(rng, 0.025, 0.045), "blade_thickness": uniform(rng, 0.0015, 0.0025)}


def build_knife(handle_length, handle_width, handle_thickness, blade_length, blade_width, blade_thickness):
    """A knife lying flat: a rounded handle on the table, the blade (straight spine on +y, the edge curving up to the
    tip) at the handle's mid-height beyond it."""
    handle = rounded_box([handle_length, handle_width, handle_thickness], min(0.005, 0.45 * handle_thickness),
                         [handle_length / 2, 0.0, handle_thickness / 2])
    x0, half = handle_length - 0.01, blade_width / 2
    t = np.linspace(0.0, 1.0, 12)
    edge = np.stack([x0 + blade_length * (0.55 + 0.45 * t), -half + 1.7 * half * t**2], axis=1)
    outline = np.vstack([[[x0, -half], [x0, half], [x0 + 0.85 * blade_length, half]], edge])
    mid = handle_thickness / 2
    blade = hull(np.vstack([np.column_stack([outline, np.full(len(outline), mid + s * blade_thickness / 2)]) for s in (-1, 1)]))
    return boolean("union", [handle, blade])


def spoon_params(rng) -> dict:
    """Teaspoons to serving spoons: bowl 4.5-7 cm long, 3-4.5 cm wide, 8-14 mm deep with a 1.8-2.5 mm shell; handle
    9-14 cm long, 9-14 mm wide, 2.5-3.5 mm thick."""
    return {"bowl_length": uniform(rng, 0.045, 0.07), "bowl_width": uniform(rng, 0.03, 0.045), "bowl_depth": uniform(rng, 0.008, 0.014),
            "shell": uniform(rng, 0.0018, 0.0025), "handle_length": uniform(rng, 0.09, 0.14), "handle_width": uniform(rng, 0.009, 0.014),
            "handle_thickness": uniform(rng, 0.0025, 0.0035)}


def build_spoon(bowl_length, bowl_width, bowl_depth, shell, handle_length, handle_width, handle_thickness):
    """A spoon resting on its bowl's bottom and its handle's end: (half-ellipsoid bowl ∪ a handle sloping down from
    the rim to the table) − the bowl's hollow."""
    import trimesh

    a, b, c = bowl_length / 2, bowl_width / 2, bowl_depth

    def ellipsoid(radii):
        sphere = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
        sphere.apply_scale(radii)
        sphere.apply_translation([0.0, 0.0, c])
        return sphere

    top = trimesh.creation.box(extents=[4 * a, 4 * b, 2 * c])
    top.apply_translation([0.0, 0.0, 2 * c])
    bowl = boolean("difference", [ellipsoid([a, b, c]), top])
    end = a + handle_length
    neck = [[a - 0.004, y, z] for y in (-0.3 * handle_width, 0.3 * handle_width) for z in (c - handle_thickness, c)]
    paddle = _circle((end - 0.5 * handle_width, 0.0), 0.5 * handle_width, [0.0, handle_thickness])
    handle = hull(np.vstack([neck, paddle]))
    return boolean("difference", [boolean("union", [bowl, handle]), ellipsoid([a - shell, b - shell, c - shell])])


def scissors_params(rng) -> dict:
    """Closed scissors lying flat: blades 7-12 cm long and 12-18 mm wide at the pivot, 4-6 mm thick together; two
    finger loops of 12-18 mm centre radius (stretched 1.2-1.6x along the scissors), rings 6-9 mm thick."""
    return {"blade_length": uniform(rng, 0.07, 0.12), "blade_width": uniform(rng, 0.012, 0.018), "thickness": uniform(rng, 0.004, 0.006),
            "loop_radius": uniform(rng, 0.012, 0.018), "loop_tube_radius": uniform(rng, 0.003, 0.0045),
            "loop_stretch": uniform(rng, 1.2, 1.6), "shank_length": uniform(rng, 0.015, 0.03)}


def build_scissors(blade_length, blade_width, thickness, loop_radius, loop_tube_radius, loop_stretch, shank_length):
    """Scissors: the closed blades (one tapered hull) on +x of the pivot, shanks back to two flat rings side by side."""
    import trimesh

    blades = hull(np.vstack([_circle((0.0, 0.0), blade_width / 2, [0.0, thickness]),
                             _circle((blade_length, 0.0), 0.001, [0.0, thickness], count=8)]))
    parts = [blades]
    centre_x = -(shank_length + loop_stretch * loop_radius)
    offset_y = 0.95 * (loop_radius + loop_tube_radius)
    for side in (-1.0, 1.0):
        ring = trimesh.creation.torus(loop_radius, loop_tube_radius, major_sections=48, minor_sections=16)
        ring.apply_scale([loop_stretch, 1.0, 1.0])
        ring.apply_translation([centre_x, side * offset_y, loop_tube_radius])
        parts.append(ring)
        front = [centre_x + loop_stretch * loop_radius, side * offset_y * 0.6, loop_tube_radius]
        parts.append(rod_between(front, [0.0, side * 0.003, loop_tube_radius], loop_tube_radius, sections=16))
    return boolean("union", parts)


def pliers_params(rng) -> dict:
    """Combination and long-nose pliers lying flat: handles 10-14 cm long and 10-14 mm thick, their ends 2.5-4 cm
    apart; jaws 3-5 cm long, 14-20 mm wide at the pivot, 8-12 mm thick; a pivot disc 16-22 mm across."""
    return {"handle_length": uniform(rng, 0.10, 0.14), "handle_radius": uniform(rng, 0.005, 0.007), "spread": uniform(rng, 0.025, 0.04),
            "jaw_length": uniform(rng, 0.03, 0.05), "jaw_width": uniform(rng, 0.014, 0.02), "jaw_thickness": uniform(rng, 0.008, 0.012),
            "pivot_radius": uniform(rng, 0.008, 0.011)}


def build_pliers(handle_length, handle_radius, spread, jaw_length, jaw_width, jaw_thickness, pivot_radius):
    """Pliers: tapered jaws on +x of a pivot disc, two handles (two capsules each, bending apart) toward -x."""
    jaws = hull(np.vstack([_circle((0.0, 0.0), jaw_width / 2, [0.0, jaw_thickness]),
                           _circle((jaw_length, 0.0), 0.0025, [0.0, jaw_thickness], count=8)]))
    pivot = rod_between([0.0, 0.0, 0.0], [0.0, 0.0, jaw_thickness], pivot_radius, rounded=False)
    parts = [jaws, pivot]
    z = handle_radius
    for side in (-1.0, 1.0):
        root = [0.0, side * 0.004, z]
        knee = [-0.45 * handle_length, side * 0.35 * spread, z]
        end = [-handle_length, side * spread / 2, z]
        parts += [rod_between(root, knee, handle_radius, sections=16), rod_between(knee, end, handle_radius, sections=16)]
    return boolean("union", parts)


# family -> (parameter draw, builder), in round-robin order.
TOOL_FAMILIES: dict[str, tuple] = {
    "screwdriver": (screwdriver_params, build_screwdriver),
    "knife": (knife_params, build_knife),
    "spoon": (spoon_params, build_spoon),
    "scissors": (scissors_params, build_scissors),
    "pliers": (pliers_params, build_pliers),
}
