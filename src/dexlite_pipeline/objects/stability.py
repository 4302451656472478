"""Table-stability test (PyBullet, DIRECT mode): does an object stand still where it is put?

Each object, at a fixed scale in its file orientation, is tilted by a small seeded angle
about a random horizontal axis (a real table is never perfectly level, and a shape balanced
exactly on a point never falls in a perfect simulation), placed with its lowest point on a
table plane and simulated under gravity. It is stable when its centre of mass moved less
than ``max_lateral_m`` sideways and it turned less than ``max_rotation_deg``. With ``settle``
an object that falls over is dropped once more from the pose it came to rest in and, when it
stands there, is used in that pose (a file's orientation is arbitrary; the table decides how an
object lies): the stability table's ``settled`` column names such objects.

The collision shape is the object's convex pieces (one compound body). The mass, the
*true* centre of mass and the inertia tensor come from the watertight mesh at a uniform
density; PyBullet would otherwise put the centre of mass at the mesh origin, which makes
almost everything look stable.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import logging
import math
import os
import sys
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexlite_pipeline.objects.config import StabilityConfig
from dexlite_pipeline.objects.rest_pose import REST_POSE_COLUMNS, RecordedRest, support_plane_from_rest

# Every row also records the object's resting pose after settling (objects.rest_pose.REST_POSE_COLUMNS; NaN
# where not simulated): the pose later stages put the object in, with the table plane below it.
STABILITY_COLUMNS = ["object_id", "lateral_displacement_m", "rotation_deg", "stable", "reason", "settled", *REST_POSE_COLUMNS]
STABILITY_REQUIRED_COLUMNS = ("object_id", "stable")  # what the stages that read the table use
GRAVITY_M_S2 = 9.81
# A recorded resting pose fits the prepared mesh when the support plane it implies is this close to the recorded one: the
# plane is recomputed from the same vertices, so only float rounding of the mesh file separates the two.
RECORDED_NORMAL_TOLERANCE_DEG = 0.1
RECORDED_OFFSET_TOLERANCE = 1e-4  # normalized units (0.01 mm on a 10 cm object)
RECORDED_REASON = "resting pose recorded by the grasp dataset, not simulated (prepared without collision pieces: objects.dataset_collision false)"

log = logging.getLogger(__name__)


def import_pybullet():
    """The ``pybullet`` module, imported without its 'pybullet build time' banner.

    The C extension prints the banner to standard error when the module loads, below
    Python's ``sys.stderr``, so descriptors 1 and 2 point at /dev/null during the import
    (C's buffers flushed before they are restored).
    """
    import ctypes

    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    sys.stdout.flush()
    sys.stderr.flush()
    saved = {fd: os.dup(fd) for fd in (1, 2)}
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd in saved:
            os.dup2(devnull, fd)
        import pybullet

        ctypes.CDLL(None).fflush(None)
    finally:
        for fd, copy in saved.items():
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)
    return pybullet


@dataclass(frozen=True)
class StabilityResult:
    object_id: str
    lateral_displacement_m: float
    rotation_deg: float
    stable: bool
    reason: str
    rest_pose: dict = field(default_factory=dict)  # objects.rest_pose.REST_POSE_COLUMNS -> value (absent: NaN)
    settled: bool = False  # stable only when dropped again from where it first came to rest (StabilityConfig.settle)

    def row(self) -> dict:
        base = {c: getattr(self, c) for c in STABILITY_COLUMNS if c not in REST_POSE_COLUMNS}
        return {**base, **{c: float(self.rest_pose.get(c, math.nan)) for c in REST_POSE_COLUMNS}}


def tilt_rotation(object_id: str, tilt_deg: float, seed: int) -> np.ndarray:
    """Rotation by ``tilt_deg`` about a horizontal axis drawn from (seed, object id): (3, 3)."""
    rng = np.random.default_rng([seed, zlib.crc32(object_id.encode())])
    heading = rng.uniform(0.0, 2.0 * math.pi)
    axis = np.array([math.cos(heading), math.sin(heading), 0.0])
    angle = math.radians(tilt_deg)
    cross = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * cross + (1 - math.cos(angle)) * cross @ cross


def _quaternion_xyzw(rotation: np.ndarray) -> list[float]:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(rotation).as_quat().tolist()


def rotation_angle_deg(q_from, q_to) -> float:
    """Angle of the rotation taking orientation ``q_from`` to ``q_to`` (xyzw quaternions)."""
    dot = abs(float(np.dot(np.asarray(q_from), np.asarray(q_to))))
    return math.degrees(2.0 * math.acos(min(1.0, dot)))


def mass_properties(mesh, scale: float, density_kg_m3: float) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """Mass (kg), centre of mass (m, mesh frame), principal moments (kg m^2) and axes (columns) at ``scale``."""
    volume_m3 = float(mesh.volume) * scale**3
    mass = density_kg_m3 * volume_m3
    com = np.asarray(mesh.center_mass, dtype=np.float64) * scale
    # trimesh's inertia is for density 1 in mesh units: scale^5 for lengths, times the density.
    inertia = np.asarray(mesh.moment_inertia, dtype=np.float64) * density_kg_m3 * scale**5
    moments, axes = np.linalg.eigh(inertia)
    if np.linalg.det(axes) < 0:
        axes[:, 0] = -axes[:, 0]
    return mass, com, np.maximum(moments, 1e-12), axes


def simulate_object(
    mesh, piece_files: list[Path], object_id: str, config: StabilityConfig, seed: int
) -> StabilityResult:
    """Drop one object (watertight ``mesh`` for mass properties, convex ``piece_files`` to collide) on a table.

    With ``config.settle``, an object that does not stand in its file orientation is dropped once more from the pose
    it came to rest in (tilted again by the seeded angle): stable when it stands there (``settled`` true; its resting
    pose is that second drop's). An object stable in its file orientation is judged by the first drop alone.
    """
    if not piece_files:
        return StabilityResult(object_id, math.nan, math.nan, False, "no convex pieces to simulate")
    mass_props = mass_properties(mesh, config.scale, config.density_kg_m3)
    tilt = tilt_rotation(object_id, config.tilt_deg, seed)
    first = _drop(mesh, piece_files, tilt, mass_props, config)
    if first.stable or not config.settle or not first.rest_pose:
        return dataclasses.replace(first, object_id=object_id)
    from scipy.spatial.transform import Rotation

    rested = Rotation.from_quat([first.rest_pose[c] for c in REST_POSE_COLUMNS[:4]]).as_matrix()
    second = _drop(mesh, piece_files, tilt @ rested, mass_props, config)
    if second.stable:
        return dataclasses.replace(second, object_id=object_id, settled=True)
    return dataclasses.replace(first, object_id=object_id, reason=f"{first.reason}; dropped again from where it came to rest: {second.reason}")


def _drop(mesh, piece_files: list[Path], orientation: np.ndarray, mass_props: tuple, config: StabilityConfig) -> StabilityResult:
    """One drop: the mesh frame turned by ``orientation`` (3, 3), its lowest point on the table, simulated and judged."""
    pb = import_pybullet()
    s = config.scale
    mass, com, moments, axes = mass_props
    tilt = orientation
    lowest = float((np.asarray(mesh.vertices) * s @ tilt.T)[:, 2].min())
    client = pb.connect(pb.DIRECT)
    try:
        pb.setGravity(0, 0, -GRAVITY_M_S2, physicsClientId=client)
        pb.setPhysicsEngineParameter(
            fixedTimeStep=config.timestep_s,
            numSolverIterations=config.solver_iterations,
            deterministicOverlappingPairs=1,
            physicsClientId=client,
        )
        table = pb.createMultiBody(0, pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=client), physicsClientId=client)
        shape = pb.createCollisionShapeArray(
            [pb.GEOM_MESH] * len(piece_files),
            fileNames=[str(f) for f in piece_files],
            meshScales=[[s, s, s]] * len(piece_files),
            physicsClientId=client,
        )
        if shape < 0:
            return StabilityResult("", math.nan, math.nan, False, "PyBullet could not build the collision shape")
        body = pb.createMultiBody(
            baseMass=mass,
            baseCollisionShapeIndex=shape,
            basePosition=[0.0, 0.0, -lowest],
            baseOrientation=_quaternion_xyzw(tilt),
            baseInertialFramePosition=com.tolist(),
            baseInertialFrameOrientation=_quaternion_xyzw(axes),
            physicsClientId=client,
        )
        for uid in (table, body):
            pb.changeDynamics(
                uid, -1, lateralFriction=config.friction, rollingFriction=0.0, spinningFriction=0.0,
                restitution=0.0, collisionMargin=config.collision_margin_m, physicsClientId=client,
            )
        pb.changeDynamics(body, -1, localInertiaDiagonal=moments.tolist(), physicsClientId=client)
        start_pos, start_orn = pb.getBasePositionAndOrientation(body, physicsClientId=client)
        for _ in range(int(round(config.duration_s / config.timestep_s))):
            pb.stepSimulation(physicsClientId=client)
        end_pos, end_orn = pb.getBasePositionAndOrientation(body, physicsClientId=client)
    finally:
        pb.disconnect(client)
    result = judge("", np.asarray(start_pos), start_orn, np.asarray(end_pos), end_orn, config)
    if np.isfinite(end_pos).all() and np.isfinite(end_orn).all():
        result = dataclasses.replace(result, rest_pose=rest_pose(mesh, np.asarray(end_pos), end_orn, com, axes))
    return result


def rest_pose(mesh, com_position, com_orientation, com, axes) -> dict:
    """The mesh frame's resting pose from PyBullet's base state, and the support plane it implies.

    PyBullet reports the base's inertial frame (centre of mass ``com`` with principal ``axes``
    as its orientation), not the mesh frame: R_mesh = R_inertial·axesᵀ, origin = p − R_mesh·com.
    """
    from scipy.spatial.transform import Rotation

    rotation = Rotation.from_quat(np.asarray(com_orientation, dtype=np.float64)).as_matrix() @ axes.T
    origin = np.asarray(com_position, dtype=np.float64) - rotation @ com
    plane = support_plane_from_rest(np.asarray(mesh.vertices), rotation)
    values = dict(zip(REST_POSE_COLUMNS[:4], Rotation.from_matrix(rotation).as_quat().tolist()))
    values.update(zip(REST_POSE_COLUMNS[4:7], plane.normal))
    values[REST_POSE_COLUMNS[7]] = plane.offset
    values[REST_POSE_COLUMNS[8]] = float(origin[2])
    return values


def judge(object_id: str, start_pos, start_orn, end_pos, end_orn, config: StabilityConfig) -> StabilityResult:
    """Stable when the centre of mass moved and the body turned less than the thresholds."""
    if not (np.isfinite(end_pos).all() and np.isfinite(end_orn).all()):
        return StabilityResult(object_id, math.nan, math.nan, False, "simulation diverged (non-finite state)")
    lateral = float(np.linalg.norm(end_pos[:2] - start_pos[:2]))
    rotation = rotation_angle_deg(start_orn, end_orn)
    problems = []
    if end_pos[2] < -config.scale:
        problems.append(f"fell through the table (centre of mass at z = {end_pos[2]:.3f} m)")
    if lateral >= config.max_lateral_m:
        problems.append(f"moved {lateral:.3f} m (limit {config.max_lateral_m} m)")
    if rotation >= config.max_rotation_deg:
        problems.append(f"rotated {rotation:.1f} deg (limit {config.max_rotation_deg} deg)")
    reason = "unstable: " + "; ".join(problems) if problems else ""
    return StabilityResult(object_id, lateral, rotation, not problems, reason)


def recorded_rest_result(mesh, object_id: str, rest: RecordedRest, config: StabilityConfig) -> StabilityResult:
    """The stability row of an object that stands in a grasp dataset's recorded resting pose (not simulated): stable, with
    that pose, when the support plane it implies on ``mesh`` is the recorded one; otherwise not stable, saying how far apart
    (the rebuilt mesh is not the one the dataset's grasps were made on)."""
    from scipy.spatial.transform import Rotation

    rotation = Rotation.from_quat(np.asarray(rest.quaternion_xyzw, dtype=np.float64)).as_matrix()
    plane = support_plane_from_rest(np.asarray(mesh.vertices), rotation)
    recorded = np.asarray(rest.support_normal, dtype=np.float64)
    angle = math.degrees(math.acos(float(np.clip(np.dot(plane.normal, recorded / np.linalg.norm(recorded)), -1.0, 1.0))))
    offset_gap = abs(plane.offset - rest.support_offset)
    if angle > RECORDED_NORMAL_TOLERANCE_DEG or offset_gap > RECORDED_OFFSET_TOLERANCE:
        return StabilityResult(object_id, math.nan, math.nan, False,
                               f"the dataset's resting pose does not fit the prepared mesh (table normal {angle:.2f} deg, "
                               f"height {offset_gap:.2g} normalized units apart)")
    values = dict(zip(REST_POSE_COLUMNS[:4], rest.quaternion_xyzw))
    values.update(zip(REST_POSE_COLUMNS[4:7], rest.support_normal))
    values[REST_POSE_COLUMNS[7]] = rest.support_offset
    values[REST_POSE_COLUMNS[8]] = rest.support_offset * config.scale  # the origin's height above the table (top at z = 0)
    return StabilityResult(object_id, math.nan, math.nan, True, RECORDED_REASON, rest_pose=values)


def simulate_asset(item: tuple[str, str], config: StabilityConfig, seed: int) -> dict:
    """Stability row of one prepared object, ``item`` = (object id, asset folder): dropped on the table, or, for an object
    prepared without collision pieces in a grasp dataset's recorded pose (its meta.json's ``recorded_rest_pose``), that pose."""
    import trimesh

    object_id, folder = item
    directory = Path(folder)
    mesh = trimesh.load(directory / "mesh.obj", force="mesh", process=False)
    pieces = sorted((directory / "convex").glob("*.obj"))
    recorded = json.loads((directory / "meta.json").read_text()).get("recorded_rest_pose") if not pieces else None
    if recorded:
        return recorded_rest_result(mesh, object_id, RecordedRest.from_dict(recorded), config).row()
    return simulate_object(mesh, pieces, object_id, config, seed).row()


def _failed_row(item: tuple[str, str], message: str) -> dict:
    first = message.splitlines()[0] if message else "unknown error"
    return StabilityResult(item[0], math.nan, math.nan, False, f"simulation failed: {first}").row()


def stability_table(catalog, objects_dirs: list[str], config: StabilityConfig, seed: int, workers: int):
    """One row per catalog object: simulated for ok objects, rejected ones carried with their reason."""
    import pandas as pd

    from dexlite_pipeline.objects.assets import ObjectAssetError, find_asset_dir
    from dexlite_pipeline.parallel import resilient_map
    from dexlite_pipeline.progress import ProgressLog

    ok = catalog["status"] == "ok"
    rows, items = [], []
    for object_id in sorted(catalog.loc[ok, "object_id"].astype(str)):
        try:
            items.append((object_id, str(find_asset_dir(objects_dirs, object_id))))
        except ObjectAssetError as exc:
            rows.append(StabilityResult(object_id, math.nan, math.nan, False, f"not simulated: {exc}").row())
    task = functools.partial(simulate_asset, config=config, seed=seed)
    progress = ProgressLog(log, "stability test", len(items), unit="objects")
    rows += resilient_map(task, items, workers, _failed_row, lambda index: progress.advance())
    for row in catalog[~ok].itertuples():
        reason = getattr(row, "reason", "") or "no reason recorded"
        rows.append(StabilityResult(str(row.object_id), math.nan, math.nan, False, f"not simulated: rejected by prepare_objects ({reason})").row())
    table = pd.DataFrame(rows, columns=STABILITY_COLUMNS).sort_values("object_id", kind="stable").reset_index(drop=True)
    table["stable"] = table["stable"].astype(bool)
    return table


def read_stability_table(path: str | Path):
    """A stability table (.parquet) with ``STABILITY_REQUIRED_COLUMNS`` and a boolean ``stable`` (one-line errors naming the file)."""
    import pandas as pd

    from dexlite_pipeline.objects.assets import read_object_table

    table = read_object_table(path, "stability table", STABILITY_REQUIRED_COLUMNS, "stability_filter")
    if not pd.api.types.is_bool_dtype(table["stable"]):
        raise ValueError(f"{path}: stability column 'stable' holds {table['stable'].dtype}, expected true/false")
    return table


def stable_object_ids(path: str | Path) -> set[str]:
    """Ids of the objects a stability table marks stable."""
    table = read_stability_table(path)
    return set(table.loc[table["stable"].to_numpy(dtype=bool, na_value=False), "object_id"].astype(str))


class NoObjectToTest(ValueError):
    """Catalogs without a single prepared (ok) object: nothing to test."""


def stability_filter(objects_dirs: list[str], seed: int, config: StabilityConfig, workers: int):
    """The stability table of every object in the catalogs of ``objects_dirs`` (first catalog naming an object wins).

    Raises ``NoObjectToTest`` when no catalog holds a prepared object.
    """
    import pandas as pd

    from dexlite_pipeline.objects.assets import read_catalog

    catalog = pd.concat([read_catalog(d) for d in objects_dirs], ignore_index=True).drop_duplicates("object_id", keep="first")
    if not (catalog["status"] == "ok").any():
        raise NoObjectToTest(f"{', '.join(map(str, objects_dirs))}: no prepared object to test ({len(catalog)} in the catalogs, all rejected)")
    return stability_table(catalog, objects_dirs, config, seed, workers)
