"""Organic shape families: apples, pears, bananas, potatoes and toy figures, irregular and at real size.

Each is one closed solid resting on the table (+z up, lowest point on z = 0) with a small flat where it touches
(real fruit settles on a flattened patch; a perfectly round bottom would roll in the table test). Apples and potatoes
are star-shaped: an icosphere whose radius varies smoothly with direction (``household_shapes.star_solid``), so they
are closed without booleans; a pear is a revolved two-bulb profile; a banana a tube swept along an arc; a toy figure
the smooth union of capsules meshed from its implicit surface (manifold3d marching tetrahedra).
"""

from __future__ import annotations

import math

import numpy as np

from dexlite_pipeline.objects.household_shapes import (
    boolean,
    flatten_below,
    implicit_solid,
    revolve,
    rod_between,
    smooth_min,
    star_solid,
    swept_tube,
    uniform,
)


def _rest_on_flat(mesh, depth: float):
    """``mesh`` with its lowest ``depth`` (m) flattened onto the table plane, then moved so that plane is z = 0."""
    flatten_below(mesh, mesh.bounds[0][2] + depth)
    mesh.apply_translation([0.0, 0.0, -mesh.bounds[0][2]])
    return mesh


def apple_params(rng) -> dict:
    """Apples: 7-9.5 cm across, 82-95% as tall, five faint lobes (1-3% of the radius), dimples at stem and calyx,
    a stem 1-2 cm long and 3-5 mm thick."""
    return {"radius": uniform(rng, 0.035, 0.0475), "squash": uniform(rng, 0.82, 0.95), "lobe": uniform(rng, 0.01, 0.03),
            "lobe_phase": uniform(rng, 0.0, 2 * math.pi), "top_dimple": uniform(rng, 0.1, 0.2), "bottom_dimple": uniform(rng, 0.05, 0.12),
            "stem_length": uniform(rng, 0.01, 0.02), "stem_radius": uniform(rng, 0.0015, 0.0025), "stem_tilt_deg": uniform(rng, 0.0, 25.0)}


def build_apple(radius, squash, lobe, lobe_phase, top_dimple, bottom_dimple, stem_length, stem_radius, stem_tilt_deg):
    """An apple: a squashed sphere with lobes and polar dimples standing on a flat 3 mm deep, its stem on top."""

    def radius_of(d):
        polar = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
        ellipse = radius / np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2 + (d[:, 2] / squash) ** 2)
        lobes = 1.0 + lobe * np.cos(5 * np.arctan2(d[:, 1], d[:, 0]) + lobe_phase) * np.sin(polar) ** 2
        dimples = 1.0 - top_dimple * np.exp(-((polar / 0.35) ** 2)) - bottom_dimple * np.exp(-(((math.pi - polar) / 0.4) ** 2))
        return ellipse * lobes * dimples

    body = star_solid(radius_of)
    top = radius * squash * (1.0 - top_dimple)
    tilt = math.radians(stem_tilt_deg)
    stem = rod_between([0.0, 0.0, top - 0.004], [stem_length * math.sin(tilt), 0.0, top + stem_length * math.cos(tilt)], stem_radius,
                       sections=12)
    return _rest_on_flat(boolean("union", [body, stem]), 0.003)


def pear_params(rng) -> dict:
    """Pears: a lower bulb 6-8 cm across, an upper one 50-65% of its radius centred 1.1-1.5 bulb radii higher
    (9-13 cm tall in all), standing on a flat 40-50% of the bulb's radius across, a stem 1.5-3 cm long."""
    return {"radius": uniform(rng, 0.03, 0.04), "top_fraction": uniform(rng, 0.5, 0.65), "top_height": uniform(rng, 1.1, 1.5),
            "flat": uniform(rng, 0.4, 0.5), "stem_length": uniform(rng, 0.015, 0.03), "stem_radius": uniform(rng, 0.0015, 0.0025),
            "stem_tilt_deg": uniform(rng, 5.0, 30.0)}


def build_pear(radius, top_fraction, top_height, flat, stem_length, stem_radius, stem_tilt_deg):
    """A pear: the profile r(z) = (r1^4 + r2^4)^(1/4) of two circles (a smooth neck between them), revolved; cut flat
    where the lower circle is ``flat`` x its radius wide."""
    upper, centre = radius * top_fraction, radius * top_height
    bottom = -radius * math.sqrt(1.0 - flat**2)
    top = centre + upper
    z = bottom + (top - bottom) * (1 - np.cos(np.linspace(0.0, math.pi, 64))) / 2  # denser near both ends
    lower_r = np.sqrt(np.clip(radius**2 - z**2, 0.0, None))
    upper_r = np.sqrt(np.clip(upper**2 - (z - centre) ** 2, 0.0, None))
    r = (lower_r**4 + upper_r**4) ** 0.25
    body = revolve(np.vstack([[[0.0, bottom]], np.stack([r[:-1], z[:-1]], axis=1), [[0.0, top]]]))
    tilt = math.radians(stem_tilt_deg)
    stem = rod_between([0.0, 0.0, top - 0.005], [stem_length * math.sin(tilt), 0.0, top + stem_length * math.cos(tilt)], stem_radius,
                       sections=12)
    mesh = boolean("union", [body, stem])
    mesh.apply_translation([0.0, 0.0, -mesh.bounds[0][2]])
    return mesh


def banana_params(rng) -> dict:
    """Bananas lying on their side: 15-22 cm along the curve (an arc of 12-20 cm radius), 32-40 mm thick in the
    middle tapering to a third at the ends, five faint ridges, a stalk 1.5-3 cm long and 9-12 mm thick."""
    return {"arc_radius": uniform(rng, 0.12, 0.20), "length": uniform(rng, 0.15, 0.22), "radius": uniform(rng, 0.016, 0.02),
            "ridge": uniform(rng, 0.03, 0.07), "stalk_length": uniform(rng, 0.015, 0.03), "stalk_radius": uniform(rng, 0.0045, 0.006)}


def build_banana(arc_radius, length, radius, ridge, stalk_length, stalk_radius):
    """A banana: a tube swept along an arc parallel to the table, thickest in the middle, every section touching the
    table, with a straight stalk rising at one end and a 2 mm flat along its underside."""
    angle = length / arc_radius
    s = np.linspace(0.0, 1.0, 48)
    phi = (s - 0.5) * angle
    radii = radius * (0.33 + 0.67 * np.sin(math.pi * s) ** 0.6)
    # Each section's bottom on the table (centre height = its radius), so it lies along its whole length.
    centres = np.stack([arc_radius * np.sin(phi), arc_radius * (1 - np.cos(phi)), radii], axis=1)
    radii[0] = radii[-1] = 0.35 * radius * 0.5  # rounded tip and stalk end
    direction = centres[-2] - centres[-3]
    direction[2] = 0.3 * np.linalg.norm(direction[:2])  # the stalk rises a little, clear of the table
    direction /= np.linalg.norm(direction)
    stalk = centres[-2] + direction * np.linspace(0.0, stalk_length, 8)[1:, None]
    centres = np.vstack([centres[:-1], stalk])
    radii = np.concatenate([radii[:-1], np.full(len(stalk) - 1, stalk_radius), [0.5 * stalk_radius]])
    tube = swept_tube(centres, radii, section=lambda a: 1.0 + ridge * np.cos(5 * a))
    return _rest_on_flat(tube, 0.002)


def potato_params(rng) -> dict:
    """Potatoes, sweet potatoes and river stones: an ellipsoid 6-12 cm long, 60-85% as wide and 45-70% as tall, its
    radius rippled by six random waves totalling 4-10%; lying on a 3 mm flat."""
    length = uniform(rng, 0.03, 0.06)
    directions = rng.normal(size=(6, 3))
    return {"half_axes": [length, length * uniform(rng, 0.6, 0.85), length * uniform(rng, 0.45, 0.7)],
            "wave_directions": (directions / np.linalg.norm(directions, axis=1, keepdims=True)).tolist(),
            "wave_numbers": rng.uniform(1.5, 3.5, size=6).tolist(), "wave_phases": rng.uniform(0.0, 2 * math.pi, size=6).tolist(),
            "ripple": uniform(rng, 0.04, 0.10)}


def build_potato(half_axes, wave_directions, wave_numbers, wave_phases, ripple):
    """A potato: an ellipsoid whose radius in each direction is scaled by 1 + ripple/6 x the sum of six cosine waves."""
    axes = np.asarray(half_axes)
    waves = np.asarray(wave_directions) * np.asarray(wave_numbers)[:, None]

    def radius_of(d):
        ellipse = 1.0 / np.sqrt(((d / axes) ** 2).sum(axis=1))
        return ellipse * (1.0 + ripple / 6 * np.cos(d @ waves.T + np.asarray(wave_phases)).sum(axis=1))

    return _rest_on_flat(star_solid(radius_of), 0.003)


def toy_figure_params(rng) -> dict:
    """Toy figures and figurines 8-15 cm tall: a round body, a head 0.6-0.85 of the body's radius, arms at
    10-70° below the horizontal, legs 18-28% of the height on flat feet 3-4.5 limb radii long; parts blended with 5-10 mm fillets."""
    height = uniform(rng, 0.08, 0.15)
    return {"height": height, "body_radius": height * uniform(rng, 0.15, 0.22), "head_fraction": uniform(rng, 0.6, 0.85),
            "leg_fraction": uniform(rng, 0.18, 0.28), "limb_radius": height * uniform(rng, 0.05, 0.075),
            "arm_droop_deg": [uniform(rng, 10.0, 70.0), uniform(rng, 10.0, 70.0)], "arm_length": height * uniform(rng, 0.22, 0.32),
            "blend": uniform(rng, 0.005, 0.01)}


def toy_figure_capsules(height, body_radius, head_fraction, leg_fraction, limb_radius, arm_droop_deg, arm_length, blend):
    """The figure's parts as capsules (start, end, radius), metres: legs, body, head, two arms."""
    legs_top = height * leg_fraction
    head_radius = body_radius * head_fraction
    body_bottom = legs_top + 0.6 * body_radius
    head_z = height - head_radius
    body_top = head_z - head_radius - 0.4 * body_radius
    shoulder_z = body_top
    parts = [((s * 0.45 * body_radius, 0.0, 0.0), (s * 0.45 * body_radius, 0.0, body_bottom), limb_radius) for s in (-1, 1)]
    # feet: half capsules along y on the table (the cut at z = 0 flattens them), wider than the legs for a stable stance
    parts += [((s * 0.45 * body_radius, -1.2 * limb_radius, 0.0), (s * 0.45 * body_radius, 1.8 * limb_radius, 0.0), 0.9 * limb_radius)
              for s in (-1, 1)]
    parts.append(((0.0, 0.0, body_bottom), (0.0, 0.0, max(body_top, body_bottom)), body_radius))
    parts.append(((0.0, 0.0, head_z), (0.0, 0.0, head_z), head_radius))
    for s, droop in zip((-1, 1), arm_droop_deg):
        a = math.radians(droop)
        start = (s * 0.8 * body_radius, 0.0, shoulder_z)
        parts.append((start, (start[0] + s * arm_length * math.cos(a), 0.0, shoulder_z - arm_length * math.sin(a)), 0.85 * limb_radius))
    return parts


def build_toy_figure(height, body_radius, head_fraction, leg_fraction, limb_radius, arm_droop_deg, arm_length, blend):
    """A figure standing on its feet: the smooth union of its capsules (fillets of ``blend``), cut flat at z = 0."""
    parts = toy_figure_capsules(height, body_radius, head_fraction, leg_fraction, limb_radius, arm_droop_deg, arm_length, blend)

    def inside(x, y, z):
        distance = math.inf
        for (ax, ay, az), (bx, by, bz), r in parts:
            ux, uy, uz = bx - ax, by - ay, bz - az
            px, py, pz = x - ax, y - ay, z - az
            uu = ux * ux + uy * uy + uz * uz
            t = 0.0 if uu == 0.0 else min(1.0, max(0.0, (px * ux + py * uy + pz * uz) / uu))
            dx, dy, dz = px - t * ux, py - t * uy, pz - t * uz
            d = math.sqrt(dx * dx + dy * dy + dz * dz) - r
            distance = d if distance == math.inf else smooth_min(distance, d, blend)
        return -max(distance, -z)

    reach = max(max(abs(a[0]), abs(b[0])) + r for a, b, r in parts) + blend
    depth = max(max(abs(a[1]), abs(b[1])) + r for a, b, r in parts) + blend
    bounds = [-reach, -depth, -0.002, reach, depth, height + blend]
    return implicit_solid(inside, bounds, max(0.0025, height / 45))


# family -> (parameter draw, builder), in round-robin order.
ORGANIC_FAMILIES: dict[str, tuple] = {
    "apple": (apple_params, build_apple),
    "pear": (pear_params, build_pear),
    "banana": (banana_params, build_banana),
    "potato": (potato_params, build_potato),
    "toy_figure": (toy_figure_params, build_toy_figure),
}
