"""Kitchen shape families: plates, pots, pans, kettles, jugs, bottles with a handle and bevelled boxes.

Like the original twelve (``household.py``): seeded parameters in metres at real size, a builder that makes one
closed solid standing in its resting pose (+z up, the base on z = 0). Vessels are revolved profiles
(``household_shapes.vessel_curves``) and handles are tori or rods joined with manifold3d booleans; a handle is added to
the outer solid before the cavity is cut, so its ends are flush with the inside of the wall.
"""

from __future__ import annotations

import math

import numpy as np

from dexlite_pipeline.objects.household_shapes import (
    boolean,
    chamfered_box,
    handle_torus,
    open_vessel,
    revolve,
    rod_between,
    rounded_box,
    smooth_step,
    uniform,
    vessel_curves,
)


def _turned_about_z(mesh, angle: float):
    """``mesh`` turned by ``angle`` (rad) about the z axis (a handle built on +x moved to another side)."""
    import trimesh

    mesh.apply_transform(trimesh.transformations.rotation_matrix(angle, [0.0, 0.0, 1.0]))
    return mesh


def _vessel_solid_and_cavity(height, rim_radius, base_radius, wall, base_thickness, roundness):
    """(outer solid, cavity, outer wall curve) of an open vessel, for adding handles between the two booleans."""
    outer, inner = vessel_curves(height, rim_radius, base_radius, wall, base_thickness, roundness)
    solid = revolve(np.vstack([[0.0, 0.0], outer, [0.0, height]]))
    cavity = revolve(np.vstack([[0.0, base_thickness], inner, [0.0, inner[-1, 1]]]))
    return solid, cavity, outer


def plate_params(rng) -> dict:
    """Side plates to dinner plates: 18-28 cm across, 1.8-3 cm tall, 3-5 mm thick, a flat well of 55-70% the radius."""
    rim = uniform(rng, 0.09, 0.14)
    wall = uniform(rng, 0.003, 0.005)
    return {"height": uniform(rng, 0.018, 0.03), "rim_radius": rim, "base_radius": rim * uniform(rng, 0.55, 0.7), "wall": wall,
            "base_thickness": wall + uniform(rng, 0.0, 0.001), "roundness": uniform(rng, 0.2, 0.5)}


def build_plate(height, rim_radius, base_radius, wall, base_thickness, roundness):
    """A plate: a very shallow open vessel whose flat well rises to a sloping rim."""
    return open_vessel(height, rim_radius, base_radius, wall, base_thickness, roundness)


def pot_params(rng) -> dict:
    """Cooking pots: 15-24 cm across, 9-16 cm tall, 2.5-4 mm walls, two loop handles 3-4.5 cm apart at the ends and
    10-14 mm thick, reaching 2-3 cm out near the rim."""
    rim = uniform(rng, 0.075, 0.12)
    return {"height": uniform(rng, 0.09, 0.16), "rim_radius": rim, "base_radius": rim * uniform(rng, 0.95, 1.0),
            "wall": uniform(rng, 0.0025, 0.004), "base_thickness": uniform(rng, 0.004, 0.006), "handle_span": uniform(rng, 0.03, 0.045),
            "handle_reach": uniform(rng, 0.02, 0.03), "handle_tube_radius": uniform(rng, 0.005, 0.007)}


def build_pot(height, rim_radius, base_radius, wall, base_thickness, handle_span, handle_reach, handle_tube_radius):
    """A pot: (outer solid ∪ two vertical loop handles on ±x, their tops 8 mm under the rim) − cavity."""
    solid, cavity, outer = _vessel_solid_and_cavity(height, rim_radius, base_radius, wall, base_thickness, 0.0)
    centre_z = height - handle_span / 2 - handle_tube_radius - 0.008
    attach = float(np.interp(centre_z, outer[:, 1], outer[:, 0]))
    handles = [handle_torus(attach, centre_z, handle_span, handle_reach, handle_tube_radius) for _ in range(2)]
    _turned_about_z(handles[1], math.pi)
    return boolean("difference", [boolean("union", [solid, *handles]), cavity])


def pan_params(rng) -> dict:
    """Frying pans and saucepans: 18-28 cm across, 3.5-6 cm tall, 3-4 mm walls, a long handle 15-22 cm long and
    16-24 mm thick rising 8-18° from the horizontal."""
    rim = uniform(rng, 0.09, 0.14)
    return {"height": uniform(rng, 0.035, 0.06), "rim_radius": rim, "base_radius": rim * uniform(rng, 0.75, 0.85),
            "wall": uniform(rng, 0.003, 0.004), "base_thickness": uniform(rng, 0.004, 0.006), "roundness": uniform(rng, 0.2, 0.5),
            "handle_length": uniform(rng, 0.15, 0.22), "handle_radius": uniform(rng, 0.008, 0.012),
            "handle_rise_deg": uniform(rng, 8.0, 18.0)}


def build_pan(height, rim_radius, base_radius, wall, base_thickness, roundness, handle_length, handle_radius, handle_rise_deg):
    """A pan: (outer solid ∪ a capsule handle leaving the wall on +x at 70% of the height) − cavity."""
    solid, cavity, outer = _vessel_solid_and_cavity(height, rim_radius, base_radius, wall, base_thickness, roundness)
    z = 0.7 * height
    attach = float(np.interp(z, outer[:, 1], outer[:, 0]))
    rise = math.radians(handle_rise_deg)
    start = np.array([attach - wall - handle_radius, 0.0, z])
    end = start + (handle_length + wall + handle_radius) * np.array([math.cos(rise), 0.0, math.sin(rise)])
    handle = rod_between(start, end, handle_radius)
    return boolean("difference", [boolean("union", [solid, handle]), cavity])


def kettle_params(rng) -> dict:
    """Closed kettles: 17-24 cm body 14-18 cm across (narrowing up to 80-95%), a lid knob, a spout 7-10 cm long
    (24-32 mm thick at its root) rising 35-55°, and a side handle 16-22 mm thick reaching 4-5.5 cm out."""
    height = uniform(rng, 0.17, 0.24)
    return {"height": height, "radius": uniform(rng, 0.07, 0.09), "top_fraction": uniform(rng, 0.8, 0.95),
            "knob_radius": uniform(rng, 0.012, 0.018), "knob_height": uniform(rng, 0.015, 0.025),
            "spout_length": uniform(rng, 0.07, 0.1), "spout_radius": uniform(rng, 0.012, 0.016),
            "spout_rise_deg": uniform(rng, 35.0, 55.0), "spout_height": height * uniform(rng, 0.25, 0.4),
            "handle_span": height * uniform(rng, 0.45, 0.6), "handle_reach": uniform(rng, 0.04, 0.055),
            "handle_tube_radius": uniform(rng, 0.008, 0.011)}


def _frustum_between(start, end, radius_start: float, radius_end: float):
    """A truncated cone from ``start`` (radius ``radius_start``) to ``end`` (m)."""
    import trimesh

    start, end = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
    length = float(np.linalg.norm(end - start))
    cone = revolve([[0.0, 0.0], [radius_start, 0.0], [radius_end, length], [0.0, length]])
    transform = trimesh.geometry.align_vectors([0.0, 0.0, 1.0], (end - start) / length)
    transform[:3, 3] = start
    cone.apply_transform(transform)
    return cone


def build_kettle(height, radius, top_fraction, knob_radius, knob_height, spout_length, spout_radius, spout_rise_deg, spout_height,
                 handle_span, handle_reach, handle_tube_radius):
    """A kettle as one closed solid: revolved body with a rounded shoulder and a lid knob, a tapering spout on +x,
    a loop handle on -x."""
    top = radius * top_fraction
    shoulder = min(0.02, 0.2 * top)
    bend = np.linspace(0.0, math.pi / 2, 8)
    rounded = np.stack([top - shoulder + shoulder * np.cos(bend), height - shoulder + shoulder * np.sin(bend)], axis=1)
    body = revolve(np.vstack([[[0.0, 0.0], [radius - 0.006, 0.0], [radius, 0.006]], rounded,
                              [[knob_radius, height], [knob_radius, height + knob_height], [0.0, height + knob_height]]]))
    wall_at = radius + (top - radius) * spout_height / (height - shoulder)
    rise = math.radians(spout_rise_deg)
    root = np.array([wall_at - 1.5 * spout_radius, 0.0, spout_height])
    spout = _frustum_between(root, root + spout_length * np.array([math.cos(rise), 0.0, math.sin(rise)]), spout_radius, 0.6 * spout_radius)
    centre_z = height * 0.5
    attach = radius + (top - radius) * centre_z / (height - shoulder) - 0.002
    handle = _turned_about_z(handle_torus(attach, centre_z, handle_span, handle_reach, handle_tube_radius), math.pi)
    return boolean("union", [body, spout, handle])


def jug_params(rng) -> dict:
    """Pitchers and measuring jugs: 15-22 cm tall, 9-12 cm across, 3-4.5 mm walls, a handle 12-16 mm thick whose ends
    are 7-10 cm apart, and a pouring lip pulled out 5-9 mm opposite it."""
    height = uniform(rng, 0.15, 0.22)
    rim = uniform(rng, 0.045, 0.06)
    return {"height": height, "rim_radius": rim, "base_radius": rim * uniform(rng, 0.85, 1.0), "wall": uniform(rng, 0.003, 0.0045),
            "base_thickness": uniform(rng, 0.005, 0.008), "handle_span": min(uniform(rng, 0.07, 0.10), 0.55 * height),
            "handle_reach": uniform(rng, 0.03, 0.042), "handle_tube_radius": uniform(rng, 0.006, 0.008), "lip": uniform(rng, 0.005, 0.009)}


LIP_DEPTH = 0.04  # m: the lip blends into the wall over the top 4 cm


def build_jug(height, rim_radius, base_radius, wall, base_thickness, handle_span, handle_reach, handle_tube_radius, lip):
    """A jug: (outer solid ∪ a loop handle on -x) − cavity, its top 4 cm on +x pushed out radially by up to ``lip``.

    The lip is a smooth displacement of space (both wall surfaces move together, so the wall keeps its thickness);
    its slope is under 0.8 for lip ≤ 9 mm, so the map is one-to-one and the solid stays closed and unbroken."""
    solid, cavity, outer = _vessel_solid_and_cavity(height, rim_radius, base_radius, wall, base_thickness, 0.0)
    centre_z = height - handle_span / 2 - handle_tube_radius - 0.01
    attach = float(np.interp(centre_z, outer[:, 1], outer[:, 0]))
    handle = _turned_about_z(handle_torus(attach, centre_z, handle_span, handle_reach, handle_tube_radius), math.pi)
    mesh = boolean("difference", [boolean("union", [solid, handle]), cavity])
    vertices = np.array(mesh.vertices)
    radial = np.linalg.norm(vertices[:, :2], axis=1)
    towards = np.clip(vertices[:, 0] / np.maximum(radial, 1e-9), 0.0, 1.0) ** 4  # cos(angle from +x)^4 on the +x side
    weight = lip * towards * smooth_step((vertices[:, 2] - (height - LIP_DEPTH)) / LIP_DEPTH)
    vertices[:, :2] += (weight / np.maximum(radial, 1e-9))[:, None] * vertices[:, :2]
    mesh.vertices = vertices
    return mesh


def handled_bottle_params(rng) -> dict:
    """Milk and detergent jugs with a moulded handle: body 10-15 x 8-12 cm, 17-25 cm tall with 1.5-3 cm rounded
    edges, a neck 32-42 mm across, a handle 16-22 mm thick reaching 2.5-3.5 cm out of the +x side."""
    return {"width": uniform(rng, 0.10, 0.15), "depth": uniform(rng, 0.08, 0.12), "body_height": uniform(rng, 0.17, 0.25),
            "corner": uniform(rng, 0.015, 0.03), "neck_radius": uniform(rng, 0.016, 0.021), "neck_height": uniform(rng, 0.02, 0.03),
            "handle_span": uniform(rng, 0.07, 0.10), "handle_reach": uniform(rng, 0.025, 0.035), "handle_tube_radius": uniform(rng, 0.008, 0.011)}


def build_handled_bottle(width, depth, body_height, corner, neck_radius, neck_height, handle_span, handle_reach, handle_tube_radius):
    """A closed bottle: rounded-box body, a capped neck toward -x, a loop handle on the +x face under the shoulder."""
    body = rounded_box([width, depth, body_height], corner, [0.0, 0.0, body_height / 2])
    neck_x = -0.2 * width
    neck = rod_between([neck_x, 0.0, body_height - corner], [neck_x, 0.0, body_height + neck_height], neck_radius, rounded=False)
    cap = rod_between([neck_x, 0.0, body_height + neck_height - 0.012], [neck_x, 0.0, body_height + neck_height + 0.004],
                      neck_radius + 0.003, rounded=False)
    centre_z = body_height - corner - handle_span / 2 - handle_tube_radius
    handle = handle_torus(width / 2 - 0.002, centre_z, handle_span, handle_reach, handle_tube_radius)
    return boolean("union", [body, neck, cap, handle])


def bevelled_box_params(rng) -> dict:
    """Tins, gift and jewellery boxes, soap bars: 6-18 x 4-12 cm, 3-20 cm tall, every edge chamfered at 45° or rounded
    by 3-12 mm (at most a quarter of the smallest side)."""
    width, depth, height = uniform(rng, 0.06, 0.18), uniform(rng, 0.04, 0.12), uniform(rng, 0.03, 0.2)
    return {"width": width, "depth": depth, "height": height, "bevel": min(uniform(rng, 0.003, 0.012), 0.25 * min(width, depth, height)),
            "rounded": bool(rng.uniform() < 0.5)}


def build_bevelled_box(width, depth, height, bevel, rounded):
    """A box (width along x, depth along y) standing on its base, its edges chamfered or rounded by ``bevel``."""
    if rounded:
        return rounded_box([width, depth, height], bevel, [0.0, 0.0, height / 2])
    return chamfered_box([width, depth, height], bevel, [0.0, 0.0, height / 2])


# family -> (parameter draw, builder), in round-robin order.
KITCHEN_FAMILIES: dict[str, tuple] = {
    "plate": (plate_params, build_plate),
    "pot": (pot_params, build_pot),
    "pan": (pan_params, build_pan),
    "kettle": (kettle_params, build_kettle),
    "jug": (jug_params, build_jug),
    "handled_bottle": (handled_bottle_params, build_handled_bottle),
    "bevelled_box": (bevelled_box_params, build_bevelled_box),
}
