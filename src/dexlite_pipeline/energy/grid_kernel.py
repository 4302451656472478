"""``SdfBank``'s trilinear grid lookup for the compiled energy passes (numba, inlined into its callers).

The same arithmetic as ``SdfBank.signed_distance``: continuous grid coordinates u = (x − min)/h
of a normalized point, clamped to the grid's interior, the distance beyond the grid box
subtracted, and the interpolant's derivatives (per unit of grid coordinate). The interpolant
is trilinear, so its Hessian is zero on the diagonal and bilinear off it.
"""

from __future__ import annotations

import math

import numba


@numba.njit(cache=True, nogil=True, inline="always")
def grid_coordinates(grid_min, o, h, top, x, y, z):
    """(u, clamped u, each per axis) of normalized point (x, y, z) in object o's grid, and the distance beyond
    the grid box in normalized units."""
    ux, uy, uz = (x - grid_min[o, 0]) / h, (y - grid_min[o, 1]) / h, (z - grid_min[o, 2]) / h
    ucx, ucy, ucz = min(max(ux, 0.0), top), min(max(uy, 0.0), top), min(max(uz, 0.0), top)
    outside = math.sqrt(((ux - ucx) * h) ** 2 + ((uy - ucy) * h) ** 2 + ((uz - ucz) * h) ** 2)
    return ux, uy, uz, ucx, ucy, ucz, outside


@numba.njit(cache=True, nogil=True, inline="always")
def trilinear(volumes, o, ucx, ucy, ucz):
    """The interpolant at clamped grid coordinates: value, gradient (gx, gy, gz) and Hessian (hxy, hxz, hyz)."""
    bx, by, bz = int(math.floor(ucx)), int(math.floor(ucy)), int(math.floor(ucz))
    fx, fy, fz = ucx - bx, ucy - by, ucz - bz
    c000 = volumes[o, bx, by, bz]
    c100 = volumes[o, bx + 1, by, bz]
    c010 = volumes[o, bx, by + 1, bz]
    c110 = volumes[o, bx + 1, by + 1, bz]
    c001 = volumes[o, bx, by, bz + 1]
    c101 = volumes[o, bx + 1, by, bz + 1]
    c011 = volumes[o, bx, by + 1, bz + 1]
    c111 = volumes[o, bx + 1, by + 1, bz + 1]
    c00 = c000 + (c100 - c000) * fx
    c10 = c010 + (c110 - c010) * fx
    c01 = c001 + (c101 - c001) * fx
    c11 = c011 + (c111 - c011) * fx
    c0 = c00 + (c10 - c00) * fy
    c1 = c01 + (c11 - c01) * fy
    value = c0 + (c1 - c0) * fz
    gx = ((c100 - c000) * (1 - fy) + (c110 - c010) * fy) * (1 - fz) + ((c101 - c001) * (1 - fy) + (c111 - c011) * fy) * fz
    gy = (c10 - c00) * (1 - fz) + (c11 - c01) * fz
    gz = c1 - c0
    hxy = ((c110 - c010) - (c100 - c000)) * (1 - fz) + ((c111 - c011) - (c101 - c001)) * fz
    hxz = ((c101 - c001) * (1 - fy) + (c111 - c011) * fy) - ((c100 - c000) * (1 - fy) + (c110 - c010) * fy)
    hyz = (c11 - c01) - (c10 - c00)
    return value, gx, gy, gz, hxy, hxz, hyz


@numba.njit(cache=True, nogil=True, inline="always")
def axis_gradient(u, uc, top, grad_u, h, outside):
    """One axis of the distance's gradient (metres per metre): the interpolant's where the clamp passes it, else
    minus the grid box's distance's."""
    if 0.0 <= u <= top:
        return grad_u / h
    if outside > 0.0:
        return -(u - uc) * h / outside
    return 0.0


@numba.njit(cache=True, nogil=True, inline="always")
def grid_distance(volumes, o, g, grid_min, h, x, y, z, gradient):
    """The distance at normalized point (x, y, z) of object o, normalized units (positive inside); its gradient,
    metres of distance per metre of point, is written into ``gradient`` (3,)."""
    top = g - 1 - 1e-4
    ux, uy, uz, ucx, ucy, ucz, outside = grid_coordinates(grid_min, o, h, top, x, y, z)
    value, gx, gy, gz, _, _, _ = trilinear(volumes, o, ucx, ucy, ucz)
    gradient[0] = axis_gradient(ux, ucx, top, gx, h, outside)
    gradient[1] = axis_gradient(uy, ucy, top, gy, h, outside)
    gradient[2] = axis_gradient(uz, ucz, top, gz, h, outside)
    return value - outside
