"""An object's resting pose on a table, as the stability stage records it, and the support plane it gives.

A leaf below ``objects.stability`` (which writes these columns) and ``tabletop`` (which reads the
planes in every stage in tabletop mode), so neither imports the other for them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Stability-table columns of the resting pose: where each simulated object came to rest, stable or not (NaN: not simulated).
REST_QUATERNION_COLUMNS = ("rest_qx", "rest_qy", "rest_qz", "rest_qw")  # mesh frame in the world after settling (xyzw)
SUPPORT_NORMAL_COLUMNS = ("support_nx", "support_ny", "support_nz")  # table's upward normal in the object frame
SUPPORT_OFFSET_COLUMN = "support_offset"  # mesh origin's height above the table per unit scale (normalized units)
REST_HEIGHT_COLUMN = "rest_height_m"  # mesh origin's height above the table after settling, at stability.scale (m)
REST_POSE_COLUMNS = (*REST_QUATERNION_COLUMNS, *SUPPORT_NORMAL_COLUMNS, SUPPORT_OFFSET_COLUMN, REST_HEIGHT_COLUMN)


@dataclass(frozen=True)
class SupportPlane:
    """The table under one object, in its object frame: upward unit normal and origin height per unit scale."""

    normal: tuple[float, float, float]
    offset: float  # h: height of the mesh origin above the table per unit scale (normalized units)

    def offset_m(self, scale: float) -> float:
        """Height of the object's origin above the table (m) at ``scale``."""
        return float(self.offset) * float(scale)

    def as_dict(self) -> dict:
        return {"normal": [float(v) for v in self.normal], "offset": float(self.offset)}


@dataclass(frozen=True)
class RecordedRest:
    """A resting pose a grasp dataset recorded for one of its objects (objects.csv), in the prepared mesh's frame: what a
    run that only trains on the object uses instead of dropping it on the table again (``objects.dataset_collision``)."""

    quaternion_xyzw: tuple[float, float, float, float]  # the mesh frame in the world at rest
    support_normal: tuple[float, float, float]  # the table's upward normal in the object frame
    support_offset: float  # the mesh origin's height above the table per unit scale (normalized units)

    @classmethod
    def from_row(cls, row) -> "RecordedRest | None":
        """The pose in a table row with ``REST_QUATERNION_COLUMNS``, ``SUPPORT_NORMAL_COLUMNS`` and ``SUPPORT_OFFSET_COLUMN``;
        None when any of them is missing or not a number (an object of a batch made without a table)."""
        try:
            values = [float(row[c]) for c in (*REST_QUATERNION_COLUMNS, *SUPPORT_NORMAL_COLUMNS, SUPPORT_OFFSET_COLUMN)]
        except (KeyError, TypeError, ValueError):
            return None
        if not np.isfinite(values).all():
            return None
        return cls(tuple(values[:4]), tuple(values[4:7]), values[7])

    def as_dict(self) -> dict:
        return {"quaternion_xyzw": list(self.quaternion_xyzw), "support_normal": list(self.support_normal),
                "support_offset": float(self.support_offset)}

    @classmethod
    def from_dict(cls, record: dict) -> "RecordedRest":
        return cls(tuple(float(v) for v in record["quaternion_xyzw"]), tuple(float(v) for v in record["support_normal"]),
                   float(record["support_offset"]))


def support_plane_from_rest(vertices: np.ndarray, rest_rotation: np.ndarray) -> SupportPlane:
    """The support plane of a mesh (normalized ``vertices``, (V, 3)) resting with orientation ``rest_rotation`` (3, 3)."""
    normal = np.asarray(rest_rotation, dtype=np.float64).T @ np.array([0.0, 0.0, 1.0])
    normal = normal / np.linalg.norm(normal)
    offset = -float((np.asarray(vertices, dtype=np.float64) @ normal).min())
    return SupportPlane(tuple(float(v) for v in normal), offset)
