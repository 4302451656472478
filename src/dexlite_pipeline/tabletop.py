"""Tabletop mode's support planes: the table under each object, as a plane in the object's frame.

The plane's upward unit normal is n = Rᵀ·z_world (R: the prepared mesh's orientation at rest,
recorded by the stability stage) and it touches the object's lowest point, so a point x (m,
object frame) of a grasp at scale s is height(x) = n·x + s·h above it (h: ``support_offset``,
per unit of scale; negative: below). Every stage needs only (n, h) per object and the scale;
gravity in the lift test acts along −n. ``scene.table: false`` (floating mode) has no plane.
This module knows no hand (planes, tolerances, store arrays, the planes of ``dexlite grasp``'s objects);
how deep the hand reaches below a plane is ``energy.table_clearance``.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np

from dexlite_pipeline.objects.rest_pose import SUPPORT_NORMAL_COLUMNS, SUPPORT_OFFSET_COLUMN, SupportPlane

log = logging.getLogger(__name__)

# Failure reason of a grasp whose hand starts (partly) inside the table.
HAND_IN_TABLE = "hand_in_table"
# A hand point this far below the table counts as below it (float32 rounding of the hand's kinematics, 1 µm).
TABLE_TOLERANCE_M = 1e-6


def upright_plane(vertices: np.ndarray, axis: str = "+z") -> SupportPlane:
    """The support plane of a mesh standing with its ``axis`` (one of ±x, ±y, ±z) pointing up."""
    if len(axis) != 2 or axis[0] not in "+-" or axis[1] not in "xyz":
        raise ValueError(f"upright axis {axis!r}: expected one of +x, -x, +y, -y, +z, -z")
    normal = np.zeros(3)
    normal["xyz".index(axis[1])] = 1.0 if axis[0] == "+" else -1.0
    offset = -float((np.asarray(vertices, dtype=np.float64) @ normal).min())
    return SupportPlane(tuple(float(v) for v in normal), offset)


def plane_from_row(row) -> SupportPlane | None:
    """The support plane in a stability-table row (a mapping or namedtuple); None when the row has none."""
    get = row.get if hasattr(row, "get") else (lambda key, default=None: getattr(row, key, default))
    values = [get(c, math.nan) for c in (*SUPPORT_NORMAL_COLUMNS, SUPPORT_OFFSET_COLUMN)]
    if any(v is None or not math.isfinite(float(v)) for v in values):
        return None
    return SupportPlane(tuple(float(v) for v in values[:3]), float(values[3]))


class MissingSupportPlane(ValueError):
    """Tabletop mode needs an object's resting pose, and the stability table has none for it."""


class SupportPlanes:
    """The support planes of the objects in a stability table, by object id."""

    def __init__(self, planes: dict[str, SupportPlane]) -> None:
        self.planes = dict(planes)

    @classmethod
    def from_stability_table(cls, path: str | Path) -> "SupportPlanes":
        from dexlite_pipeline.objects.stability import read_stability_table

        table = read_stability_table(path)
        missing = [c for c in (*SUPPORT_NORMAL_COLUMNS, SUPPORT_OFFSET_COLUMN) if c not in table.columns]
        if missing:
            raise MissingSupportPlane(f"{path}: stability table has no resting pose (columns {', '.join(missing)}): rerun stability_filter")
        planes = {}
        for row in table.to_dict("records"):
            plane = plane_from_row(row)
            if plane is not None:
                planes[str(row["object_id"])] = plane
        return cls(planes)

    def __contains__(self, object_id: str) -> bool:
        return str(object_id) in self.planes

    def get(self, object_id: str) -> SupportPlane:
        try:
            return self.planes[str(object_id)]
        except KeyError:
            raise MissingSupportPlane(f"object {object_id}: no resting pose in the stability table") from None

    def arrays(self, object_ids, scale) -> tuple[np.ndarray, np.ndarray]:
        """Per grasp: support normal (N, 3) and the plane's offset in metres, n·x + offset_m ≥ 0 above (N,)."""
        object_ids = list(object_ids)
        normal = np.zeros((len(object_ids), 3), np.float64)
        offset = np.zeros(len(object_ids), np.float64)
        for i, object_id in enumerate(object_ids):
            plane = self.get(object_id)
            normal[i] = plane.normal
            offset[i] = plane.offset
        return normal, offset * np.asarray(scale, dtype=np.float64)


def load_support_planes(table: bool, stability_path: str | Path | None) -> SupportPlanes | None:
    """The stability table's support planes in tabletop mode, None in floating mode."""
    if not table:
        return None
    if stability_path is None:
        raise MissingSupportPlane("tabletop mode (scene.table: true) needs the stability table (--stability)")
    return SupportPlanes.from_stability_table(stability_path)


def store_arrays(normal: np.ndarray, offset_m: np.ndarray) -> dict[str, np.ndarray]:
    """The per-grasp arrays a grasp store records in tabletop mode (so a grasp is reproducible)."""
    return {"support_normal": np.asarray(normal, np.float32), "support_offset_m": np.asarray(offset_m, np.float32)}


def store_attrs(table: bool) -> dict:
    """Root attributes recording the scene mode of a grasp store."""
    return {"scene": {"table": bool(table)}}


def support_arrays(planes: SupportPlanes, object_ids, scale) -> dict[str, np.ndarray]:
    """``store_arrays`` for grasps of these objects at these scales; NaN for an object without a support plane."""
    object_ids = [str(o) for o in object_ids]
    normal = np.full((len(object_ids), 3), np.nan)
    offset = np.full(len(object_ids), np.nan)
    for i, object_id in enumerate(object_ids):
        if object_id in planes:
            plane = planes.get(object_id)
            normal[i], offset[i] = plane.normal, plane.offset * float(scale[i])
    return store_arrays(normal, offset)


def reachable_on_table(lift_success, table_depth_mm) -> dict[str, float]:
    """Of the held grasps (``lift_success``), the share with no hand point below the object's table in its
    resting pose (``table_depth_mm`` within ``TABLE_TOLERANCE_M``), and how many were held and how many
    of them reach below it. NaN share when nothing was held or no grasp has a table."""
    held = np.asarray(lift_success, dtype=bool)
    depth = np.asarray(table_depth_mm, dtype=np.float64)
    measured = held & np.isfinite(depth)
    above = measured & (depth <= TABLE_TOLERANCE_M * 1000.0)
    count = int(measured.sum())
    return {
        "held_reachable_on_table_rate": float(above.sum() / count) if count else math.nan,
        "n_held_below_table": int(count - above.sum()),
    }


UPRIGHT_AXES = ("+x", "-x", "+y", "-y", "+z", "-z")


def tool_support_planes(assets, table: bool, upright_axis: str | None, stability_config, seed: int) -> tuple[SupportPlanes | None, dict[str, str]]:
    """The tables of ``dexlite grasp``'s objects, and per object a sentence saying which pose it stands in.

    Floating mode (``table`` false): None. With ``upright_axis`` the mesh stands with that axis up
    (``upright_plane``). Otherwise its stable pose: the pose it comes to rest in when set on a table
    in its file orientation (the stability stage's simulation, ``stability_config``); if that cannot be
    simulated, the file's +z is taken as up and the sentence says why.
    """
    from dexlite_pipeline.objects.stability import simulate_asset

    if not table:
        return None, {a.object_id: "no table (scene.table false): floating object, gravity along the file's -z" for a in assets}
    planes, said = {}, {}
    for asset in assets:
        vertices = np.asarray(asset.load_mesh().vertices)
        if upright_axis:
            planes[asset.object_id] = upright_plane(vertices, upright_axis)
            said[asset.object_id] = f"standing with its {upright_axis} axis up (--upright-axis), table under its lowest point"
            continue
        row = simulate_asset((asset.object_id, str(asset.directory)), stability_config, seed)
        plane = plane_from_row(row)
        if plane is None:
            planes[asset.object_id] = upright_plane(vertices, "+z")
            said[asset.object_id] = f"file orientation (+z up): its resting pose could not be simulated ({row['reason']})"
            continue
        planes[asset.object_id] = plane
        tilt = math.degrees(math.acos(max(-1.0, min(1.0, plane.normal[2]))))
        settled = "stands as in the file" if row["stable"] else f"topples from the file orientation ({row['rotation_deg']:.0f} deg)"
        said[asset.object_id] = f"stable pose: where it comes to rest on a table (PyBullet; it {settled}), up {tilt:.1f} deg from the file's +z"
    for object_id, sentence in said.items():
        log.info("object %s: %s", object_id, sentence)
    return SupportPlanes(planes), said


def planes_from_store(grasps) -> SupportPlanes | None:
    """The support planes a grasp store recorded per grasp (``support_normal``, ``support_offset_m``), by object;
    None when it recorded none (a floating store). Rows without a finite plane are skipped."""
    if "support_normal" not in grasps.arrays or "support_offset_m" not in grasps.arrays:
        return None
    normal = np.asarray(grasps.arrays["support_normal"], dtype=np.float64)
    offset = np.asarray(grasps.arrays["support_offset_m"], dtype=np.float64) / np.asarray(grasps.scale, dtype=np.float64)
    planes = {}
    for i, object_id in enumerate(str(o) for o in grasps.object_id):
        if object_id not in planes and np.isfinite(normal[i]).all() and np.isfinite(offset[i]):
            planes[object_id] = SupportPlane(tuple(float(v) for v in normal[i]), float(offset[i]))
    return SupportPlanes(planes)
