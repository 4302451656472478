"""MuJoCo lift test (and DexGraspBench's six-direction test) of grasps, parallel over cores.

Per grasp (docs/design.md, "Physics tests"):

1. Start depth: the grasp's penetration depth against the object's mesh, the one measure
   the energy filter and the report use too (``energy.penetration_term.PenetrationTerm``: object points
   inside the hand's shapes and the hand's spheres inside the object, exact near the
   surface); deeper than ``max_initial_penetration_m`` (2 mm by default) fails at once with
   reason ``initial_penetration``: a finger that starts deeper would have had to pass
   through the object, and MuJoCo's push-out would preload the grip. The overlap MuJoCo
   itself sees at the start (hand against the convex pieces, which bulge past the mesh) is
   recorded as ``initial_hull_overlap_mm``, not judged.
2. Squeeze target (geometric): every finger with a link within
   ``squeeze_contact_distance_m`` of the object moves its joints along the gradient that
   pushes those links into the object, the largest joint change being ``squeeze_rad``;
   other fingers keep their pose. The fingers start AT the grasp pose and their targets
   ramp to the squeeze target (never start at the target: DexGraspNet's false positive).
3. Close, hold, lift the hand ``lift_height_m`` in ``lift_s`` (smooth cosine profile, as a
   robot arm would move, so no velocity step hits the grasp), hold; gravity along the
   object frame's -z throughout. Lift ratio r = dz_object / dz_hand at the end; success
   if r > ``success_lift_ratio``; a ratio above 2 - ``success_lift_ratio`` is an object thrown by an
   unstable contact, not carried (``simulation_unstable``, ``launched``).

Tabletop mode (``support_planes`` given; docs/design.md, "Tabletop mode"): the scene holds the
table under the object's resting pose and gravity acts along its downward normal n; the object
starts resting on it, the hand closes and rises along n, and heights are measured along n. A
grasp with a hand shape below the table (deeper than ``tabletop.TABLE_TOLERANCE_M``) fails
before simulation with reason ``hand_in_table``, before either test. The six pushes are
DexGraspBench's test of the grip alone: the table's contacts are switched off for them (with
gravity off it would only prop the object up against the -n push).

An object that has provably left the hand (entirely below a sphere that holds the hand
in any joint configuration, falling away from it, no contacts) can never touch the hand
again, so the rest of its fall is ballistic: it is extrapolated with MuJoCo's own
semi-implicit Euler update instead of simulated, checked before every control chunk
from the start of the close. The outcome is that of a full simulation (the ratios agree
closely; MuJoCo integrates a spinning body about its frame origin, the extrapolation its
centre of mass). Without a table a dropped object keeps falling, so its ratio is strongly
negative; on a table it lands back on it and its ratio is taken as 0.

Six-direction test (optional): gravity off, fingers closed as above, then a force of
``six_dir_force_per_kg_n`` x mass along +x, -x, +y, -y, +z, -z in turn, each from the same
closed state (MuJoCo is deterministic, so restoring the saved state equals re-simulating
the close), for ``six_dir_duration_s``; a direction passes if the object stays within
``six_dir_max_translation_m`` and ``six_dir_max_rotation_deg`` (angle from |q_w|) of its
initial pose throughout. By default (``six_dir_exhaustive`` off) only grasps that lifted are
pushed, and a grasp's pushes stop at the first direction that fails: a grasp passes only if it
lifts and passes all six, which is what every report counts, and the skipped directions of a
failed grasp stay untested (NaN). Of 1,310 evaluated grasps of a default run, 2 passed six
directions without lifting; half the grasps pushed never lifted.

Modules: ``sim.squeeze`` computes the squeeze targets (step 2), ``sim.simulator`` simulates one
grasp (step 3, the early exit, the six pushes); this one checks the start (step 1) and the
table, batches each object's grasps and runs them on threads.
"""

from __future__ import annotations

import logging
import os
from collections import OrderedDict, deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import torch

from dexlite_pipeline.energy.table_clearance import hand_table_depth
from dexlite_pipeline.hand.described import is_described
from dexlite_pipeline.hand.model import ShadowHand
from dexlite_pipeline.io.grasp_store import GraspSet, invalid_grasp_reasons
from dexlite_pipeline.objects.assets import ObjectAsset, SdfBank, available_object_ids, load_asset
from dexlite_pipeline.objects.rest_pose import SupportPlane
from dexlite_pipeline.progress import ProgressLog
from dexlite_pipeline.sim.config import LiftConfig
from dexlite_pipeline.sim.described_scene import DescribedLiftScene
from dexlite_pipeline.sim.scene import LiftScene
from dexlite_pipeline.sim.simulator import GraspSimulator, _palm_quaternions
from dexlite_pipeline.sim.squeeze import squeeze_targets
from dexlite_pipeline.tabletop import HAND_IN_TABLE, TABLE_TOLERANCE_M, SupportPlanes

log = logging.getLogger(__name__)

TASK_GRASPS = 8  # grasps per task: the cores wait at most one task (~1 s) for the last one; one torch batch
PREP_BATCH = 8  # grasps per torch batch in the penetration / squeeze computations
SCENE_CACHE = 8  # compiled scenes kept per worker


@dataclass
class LiftOutcome:
    """Per-grasp results of one batch (arrays aligned with the batch)."""

    lift_ratio: np.ndarray  # float32, NaN where not simulated
    lift_success: np.ndarray  # bool
    failure_reason: np.ndarray  # object (str), '' on success
    initial_penetration_mm: np.ndarray  # float32, the start depth against the mesh
    initial_hull_overlap_mm: np.ndarray  # float32, deepest hand contact with the convex pieces at the start
    six_dir_translation_m: np.ndarray  # float32 (B, 6)
    six_dir_rotation_deg: np.ndarray  # float32 (B, 6)
    table_depth_mm: np.ndarray  # float32, deepest hand point below the table (tabletop mode; NaN otherwise)

    @classmethod
    def empty(cls, count: int) -> "LiftOutcome":
        return cls(
            table_depth_mm=np.full(count, np.nan, np.float32),
            lift_ratio=np.full(count, np.nan, np.float32),
            lift_success=np.zeros(count, bool),
            failure_reason=np.full(count, "", dtype=object),
            initial_penetration_mm=np.full(count, np.nan, np.float32),
            initial_hull_overlap_mm=np.full(count, np.nan, np.float32),
            six_dir_translation_m=np.full((count, 6), np.nan, np.float32),
            six_dir_rotation_deg=np.full((count, 6), np.nan, np.float32),
        )


# --------------------------------------------------------------------------- batches and workers
@dataclass
class LiftTask:
    """Grasps of one object for one worker call."""

    object_id: str
    objects_dirs: list[str]
    indices: np.ndarray  # positions in the caller's grasp set
    hand_pose: np.ndarray  # (B, 28) float64 ((B, 6 + J) for a hand from its MJCF)
    scale: np.ndarray  # (B,) float64
    config: LiftConfig
    table: SupportPlane | None = None  # the object's table (tabletop mode); None: floating
    max_scale: float = 0.0  # the largest scale of this object's grasps in the call (its depth measure's point set)


class _WorkerState:
    """One worker thread's caches: assets and simulators (one compiled scene per object and scale).

    MuJoCo models and data are changed in place while simulating, so every thread owns
    its own; the hand model is only read, so all threads share it. One state serves one
    ``run_lift_tests`` call, so a cached simulator's config is the call's config.
    """

    def __init__(self, hand: ShadowHand) -> None:
        self.hand = hand
        self.assets: OrderedDict[tuple, ObjectAsset] = OrderedDict()
        self.simulators: OrderedDict[tuple, GraspSimulator] = OrderedDict()
        self.measures: OrderedDict[tuple, object] = OrderedDict()

    def get_measure(self, asset: ObjectAsset, max_scale: float):
        """The judged penetration measure (a one-object ``GraspEnergy``) of ``asset`` for grasps up to ``max_scale``."""
        from dexlite_pipeline.energy.grasp_energy import GraspEnergy

        key = (str(asset.directory), float(max_scale))
        if key not in self.measures:  # only its ``judge`` is used: E_pen's own points stay at the default, coarser spacing
            self.measures[key] = GraspEnergy.from_assets(self.hand, [asset], max_scale=float(max_scale))
            while len(self.measures) > SCENE_CACHE:
                self.measures.popitem(last=False)
        self.measures.move_to_end(key)
        return self.measures[key]

    def get_asset(self, dirs: list[str], object_id: str) -> ObjectAsset:
        key = (tuple(dirs), object_id)
        if key not in self.assets:
            self.assets[key] = load_asset(dirs, object_id)
            while len(self.assets) > SCENE_CACHE:
                self.assets.popitem(last=False)
        return self.assets[key]

    def get_simulator(self, asset: ObjectAsset, scale: float, config: LiftConfig, table: SupportPlane | None = None) -> GraspSimulator:
        key = (str(asset.directory), float(scale)) if table is None else (str(asset.directory), float(scale), table)
        if key not in self.simulators:
            if is_described(self.hand):  # a hand from its MJCF: its own file and actuators (``sim.described_scene``)
                scene = DescribedLiftScene.build_for(self.hand, asset.convex_paths, float(scale), config, table)
            else:
                scene = LiftScene.build(asset.convex_paths, float(scale), config, table)
            self.simulators[key] = GraspSimulator(scene, config)
            while len(self.simulators) > SCENE_CACHE:
                self.simulators.popitem(last=False)
        self.simulators.move_to_end(key)
        return self.simulators[key]


def _squeeze_plans(hand: ShadowHand, asset: ObjectAsset, hand_pose: np.ndarray, scale: np.ndarray, config: LiftConfig) -> np.ndarray:
    """Squeeze targets (B, 22) of one object's grasps ((B, J) for a hand from its MJCF), in torch batches."""
    bank = SdfBank([asset], device=hand.device)
    targets = []
    for start in range(0, len(hand_pose), PREP_BATCH):
        pose = torch.as_tensor(hand_pose[start : start + PREP_BATCH], dtype=hand.dtype, device=hand.device)
        s = torch.as_tensor(scale[start : start + PREP_BATCH], dtype=hand.dtype, device=hand.device)
        targets.append(squeeze_targets(hand, bank, pose, s, config).targets.cpu().numpy())
    return np.concatenate(targets).astype(np.float64)


def start_depth_m(measure, hand_pose: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(B,) penetration depth (m) of grasps on the measure's one object, exact near the surface."""
    pose = torch.as_tensor(hand_pose, dtype=measure.hand.dtype, device=measure.device)
    s = torch.as_tensor(scale, dtype=measure.hand.dtype, device=measure.device)
    depth = measure.judged_depth_m(measure.hand.forward(pose), torch.zeros(len(pose), dtype=torch.long, device=measure.device), s)
    return depth.cpu().numpy().astype(np.float64)


def _error_reason(exc: Exception) -> str:
    return f"object_error: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}"


def launched(ratio: float, config: LiftConfig) -> str:
    """``simulation_unstable`` for a lift ratio above 2 - ``success_lift_ratio`` (1.1 by default), else ''.

    A held object rises with the hand (ratio about 1; the Shadow Hand's largest of 8,847 tested grasps: 1.02); one
    that rose 10% farther than the hand was thrown by a contact the solver resolved with a blow-up, not carried.
    Without this bound such a grasp would count as held (LEAP's file, 6 of 64 grasps on four household objects).
    """
    return "simulation_unstable" if ratio > 2.0 - config.success_lift_ratio else ""


def run_task(task: LiftTask, state: _WorkerState) -> tuple[np.ndarray, LiftOutcome]:
    """Lift-test one object's grasps with one worker's caches; never raises for a bad object.

    The start depth is the penetration measure against the mesh (module docstring, step 1).
    """
    cfg = task.config
    out = LiftOutcome.empty(len(task.indices))
    try:
        asset = state.get_asset(task.objects_dirs, task.object_id)
        targets = _squeeze_plans(state.hand, asset, task.hand_pose, task.scale, cfg)
        measure = state.get_measure(asset, max(task.max_scale, float(task.scale.max())))
        depth = start_depth_m(measure, task.hand_pose, task.scale)
    except Exception as exc:  # one bad object must not stop the others: record it per grasp
        log.warning("object %s: %s", task.object_id, exc)
        out.failure_reason[:] = _error_reason(exc)
        return task.indices, out
    quats = _palm_quaternions(task.hand_pose)
    table_depth = None if task.table is None else hand_table_depth(state.hand, task.hand_pose, task.table, task.scale)
    for i in np.argsort(task.scale, kind="stable"):
        if table_depth is not None:
            out.table_depth_mm[i] = table_depth[i] * 1000.0
            if table_depth[i] > TABLE_TOLERANCE_M:
                out.failure_reason[i] = HAND_IN_TABLE
                continue
        try:
            sim = state.get_simulator(asset, task.scale[i], cfg) if task.table is None else state.get_simulator(asset, task.scale[i], cfg, task.table)
        except Exception as exc:
            out.failure_reason[i] = _error_reason(exc)
            continue
        out.initial_penetration_mm[i] = depth[i] * 1000.0
        out.initial_hull_overlap_mm[i] = sim.initial_contact_depth_m(task.hand_pose[i], quats[i]) * 1000.0
        if depth[i] > cfg.max_initial_penetration_m:
            out.failure_reason[i] = "initial_penetration"
            continue
        ratio, reason = sim.lift(task.hand_pose[i], quats[i], targets[i])
        reason = launched(ratio, cfg) or reason
        out.lift_ratio[i] = ratio
        out.lift_success[i] = reason == ""
        out.failure_reason[i] = reason
        if cfg.six_directions and (cfg.six_dir_exhaustive or out.lift_success[i]):
            out.six_dir_translation_m[i], out.six_dir_rotation_deg[i] = sim.six_directions(
                task.hand_pose[i], quats[i], targets[i], stop_at_failure=not cfg.six_dir_exhaustive
            )
    return task.indices, out


def make_tasks(grasps: GraspSet, indices: np.ndarray, objects_dirs: list[str], config: LiftConfig, support_planes: SupportPlanes | None = None) -> list[LiftTask]:
    """Split the chosen grasps into per-object tasks of at most TASK_GRASPS, ordered by scale within an object."""
    tasks = []
    object_ids = grasps.object_id[indices]
    for object_id in sorted(set(object_ids.tolist())):
        rows = indices[object_ids == object_id]
        rows = rows[np.argsort(grasps.scale[rows], kind="stable")]
        max_scale = float(grasps.scale[rows].max())
        for start in range(0, len(rows), TASK_GRASPS):
            part = rows[start : start + TASK_GRASPS]
            tasks.append(
                LiftTask(
                    object_id=str(object_id),
                    objects_dirs=list(objects_dirs),
                    indices=part,
                    hand_pose=grasps.hand_pose[part].astype(np.float64),
                    scale=grasps.scale[part].astype(np.float64),
                    config=config,
                    table=None if support_planes is None else support_planes.get(str(object_id)),
                    max_scale=max_scale,
                )
            )
    return tasks


def run_lift_tests(grasps: GraspSet, objects_dirs, config: LiftConfig, threads: int = 1, support_planes: SupportPlanes | None = None,
                   known_failures: np.ndarray | None = None, hand: ShadowHand | None = None) -> dict[str, np.ndarray]:
    """Lift-test every grasp; per-grasp arrays aligned with ``grasps``.

    ``support_planes`` (tabletop mode): each object rests on its table (module docstring); the
    results add ``table_depth_mm``. Grasps of an object without a support plane fail with
    ``invalid_grasp: no resting pose``. None: floating objects.

    Invalid grasps (non-finite pose or scale, object missing from the assets) are kept,
    flagged with ``failure_reason = 'invalid_grasp: <reason>'`` and not simulated.
    ``known_failures`` (N,) reasons, '' for a grasp to test: a caller that knows a grasp fails (an
    optimization stopped as hopeless) keeps it out of the simulation; it fails with
    ``failure_reason = 'not_tested: <reason>'``. Work runs on ``threads`` threads of this process.
    Returns ``lift_ratio``, ``lift_success``, ``failure_reason``, ``initial_penetration_mm``
    and, with ``config.six_directions``, ``six_dir_success``, ``six_dir_passed`` (N, 6),
    ``six_dir_translation_m`` (N, 6) and ``six_dir_rotation_deg`` (N, 6) in ``sim.simulator.DIRECTIONS`` order.
    ``hand``: the hand of the grasps (None: the Shadow Hand); a hand from its MJCF (``hand.described.DescribedHand``,
    poses of 6 + J numbers) is simulated from its own file with its own actuators (``sim.described_scene``).
    """
    dirs = [str(objects_dirs)] if isinstance(objects_dirs, (str, os.PathLike)) else [str(d) for d in objects_dirs]
    n = len(grasps)
    reasons = invalid_grasp_reasons(grasps, available_object_ids(dirs))
    out = LiftOutcome.empty(n)
    if support_planes is not None:
        no_plane = np.array([oid not in support_planes for oid in grasps.object_id], dtype=bool)
        reasons[(reasons == "") & no_plane] = "no resting pose (tabletop mode)"
    invalid = reasons != ""
    out.failure_reason[invalid] = np.asarray([f"invalid_grasp: {r}" for r in reasons[invalid]], dtype=object)
    if known_failures is not None:
        known = (np.asarray(known_failures, dtype=object) != "") & ~invalid
        out.failure_reason[known] = np.asarray([f"not_tested: {r}" for r in np.asarray(known_failures, dtype=object)[known]], dtype=object)
        invalid = invalid | known
    tasks = make_tasks(grasps, np.flatnonzero(~invalid), dirs, config, support_planes)
    label = "lift + six-direction test" if config.six_directions else "lift test"
    progress = ProgressLog(log, label, int((~invalid).sum()), unit="grasps")
    _collect(out, _run_threads(tasks, max(1, min(int(threads or 1), len(tasks))), progress, hand))
    arrays = _as_arrays(out, config)
    if support_planes is not None:
        arrays["table_depth_mm"] = out.table_depth_mm
    return arrays


def _run_threads(tasks: list[LiftTask], workers: int, progress: ProgressLog | None = None,
                 hand: ShadowHand | None = None) -> list[tuple[np.ndarray, LiftOutcome]]:
    """Results of ``run_task`` over ``tasks`` on ``workers`` threads of this process.

    MuJoCo releases the GIL while it steps (over 90% of a grasp's CPU time) and torch while it
    computes, so threads scale like processes without their start-up (a spawned process
    spends ~1.5 CPU s importing torch and MuJoCo) or copies of the hand model. Each thread
    has its own compiled scenes. All take the next task from one queue the moment they
    finish one; the first thread takes from the back and the others from the front, and
    tasks are ordered by object and scale, so most (object, scale) scenes are compiled in
    one thread only. Torch runs one intra-op thread per worker while this runs.
    ``progress`` counts the grasps of every finished task. ``hand``: the grasps' hand (None: the Shadow Hand).
    """
    queue = deque(tasks)  # deque.pop / popleft are atomic: the threads share it without a lock
    hand = ShadowHand() if hand is None else hand

    def drain(take) -> list:
        state, done = _WorkerState(hand), []
        while True:
            try:
                task = take()
            except IndexError:
                return done
            done.append(run_task(task, state))
            if progress is not None:
                progress.advance(len(task.indices))

    if workers == 1:
        return drain(queue.popleft)
    torch_threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            futures = [pool.submit(drain, queue.pop)] + [pool.submit(drain, queue.popleft) for _ in range(workers - 1)]
            return [result for future in futures for result in future.result()]
    finally:
        torch.set_num_threads(torch_threads)


def _collect(out: LiftOutcome, results) -> None:
    for indices, part in results:
        for name in vars(out):
            getattr(out, name)[indices] = getattr(part, name)


def _as_arrays(out: LiftOutcome, config: LiftConfig) -> dict[str, np.ndarray]:
    arrays = {
        "lift_ratio": out.lift_ratio,
        "lift_success": out.lift_success,
        "failure_reason": out.failure_reason,
        "initial_penetration_mm": out.initial_penetration_mm,
        "initial_hull_overlap_mm": out.initial_hull_overlap_mm,
    }
    if config.six_directions:
        with np.errstate(invalid="ignore"):
            passed = (out.six_dir_translation_m < config.six_dir_max_translation_m) & (out.six_dir_rotation_deg < config.six_dir_max_rotation_deg)
        arrays.update(
            six_dir_success=passed.all(axis=1),
            six_dir_passed=passed,
            six_dir_translation_m=out.six_dir_translation_m,
            six_dir_rotation_deg=out.six_dir_rotation_deg,
        )
    return arrays
