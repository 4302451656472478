"""MuJoCo simulation of one grasp in one compiled scene: the lift test and DexGraspBench's six-direction test.

``GraspSimulator`` runs a grasp from its pose toward its squeeze target: the close, hold, lift and
hold of the lift test with the early exit for an object that has left the hand, and the six
pushes. The protocol, its constants and the tabletop variant are described in ``sim.lift``, which
prepares each grasp and runs the simulators. Lengths in metres, joint angles in radians, the
six-direction rotations in degrees.
"""

from __future__ import annotations

import collections
import math

import numpy as np
import torch

from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix
from dexlite_pipeline.sim.config import LiftConfig
from dexlite_pipeline.sim.scene import GRAVITY_MPS2, LiftScene

DIRECTIONS = ("+x", "-x", "+y", "-y", "+z", "-z")
DIRECTION_VECTORS = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=np.float64)


def _palm_quaternions(hand_pose: np.ndarray) -> np.ndarray:
    """(B, 4) wxyz quaternions of the palm rotations (static-axis xyz Euler)."""
    import mujoco

    rot = euler_xyz_to_matrix(torch.as_tensor(hand_pose[:, 3:6], dtype=torch.float64)).numpy()
    quats = np.zeros((len(hand_pose), 4))
    for i, r in enumerate(rot):
        mujoco.mju_mat2Quat(quats[i], r.reshape(-1))
    return quats


def _length(vector: np.ndarray) -> float:
    """Euclidean length of a 1-D float64 array, the same float as ``np.linalg.norm`` (the square root of ``dot``),
    without its argument checks (it runs after every control chunk)."""
    return math.sqrt(vector.dot(vector))


class GraspSimulator:
    """Runs the lift and six-direction tests of single grasps in one compiled scene."""

    def __init__(self, scene: LiftScene, config: LiftConfig) -> None:
        scene.configure(config)
        self.scene = scene
        self.config = config
        self.close_chunks = config.chunks(config.close_s) or [1]
        self.six_dir_chunks = config.chunks(config.six_dir_duration_s) or [1]
        self.schedule = self._lift_schedule()
        # Chunks in the settle window (0: settling off); the test starts once twice the window has passed.
        self.settle_chunks = max(1, round(config.steps(config.six_dir_settle_s) / config.control_substeps)) if config.six_dir_settle_factor > 0 else 0
        self.total_steps = sum(steps for steps, _, _ in self.schedule)
        # Per lift chunk, the palm's rise (m) along the smooth profile, or None where the palm holds still.
        self._rises = [None if f is None else config.lift_height_m * 0.5 * (1.0 - math.cos(math.pi * f)) for _, _, f in self.schedule]
        # Views into the scene's MjData (its buffers stay in place for its whole life) of what is read between chunks:
        # the object's centre of mass, the palm origin, the object's free-joint position and velocity, the palm's velocity.
        d = scene.data
        self._object_com = d.xipos[scene.object_body]
        self._palm_origin = d.xpos[scene.palm_body]
        self._object_qpos = d.qpos[scene.object_qpos]
        self._object_qvel = d.qvel[scene.object_qvel]
        self._object_linvel = self._object_qvel[:3]
        self._palm_linvel = d.qvel[scene.palm_qvel][:3]

    def _lift_schedule(self) -> list[tuple[int, float | None, float | None]]:
        """The lift timeline as control chunks: (steps, close fraction or None, lift fraction or None).

        Before a chunk the finger targets are set to ``close fraction`` of the way to the
        squeeze target, the palm to ``lift fraction`` of the smooth rise (None: unchanged).
        """
        cfg = self.config
        close_total, lift_chunks = sum(self.close_chunks), cfg.chunks(cfg.lift_s) or [1]
        lift_total = sum(lift_chunks)
        schedule = [(steps, done / close_total, None) for steps, done in zip(self.close_chunks, np.cumsum(self.close_chunks))]
        schedule += [(steps, None, None) for steps in cfg.chunks(cfg.hold_s)]
        schedule += [(steps, None, done / lift_total) for steps, done in zip(lift_chunks, np.cumsum(lift_chunks))]
        schedule += [(steps, None, None) for steps in cfg.chunks(cfg.final_hold_s)]
        return schedule

    def _reset(self, pose: np.ndarray, quat: np.ndarray) -> None:
        import mujoco

        s, m, d = self.scene, self.scene.model, self.scene.data
        mujoco.mj_resetData(m, d)
        d.qpos[s.palm_qpos] = np.concatenate([pose[:3], quat])
        d.qpos[s.joint_qpos] = pose[6:]
        d.qpos[s.object_qpos] = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
        d.mocap_pos[0] = pose[:3]
        d.mocap_quat[0] = quat
        d.ctrl[:] = pose[6:]
        mujoco.mj_forward(m, d)

    def initial_contact_depth_m(self, pose: np.ndarray, quat: np.ndarray) -> float:
        """Deepest hand-object penetration MuJoCo finds at the grasp pose (capsules and boxes vs convex pieces)."""
        self._reset(pose, quat)
        s, m, d = self.scene, self.scene.model, self.scene.data
        if d.ncon == 0:
            return 0.0
        contacts = d.contact
        body1, body2 = m.geom_bodyid[contacts.geom1], m.geom_bodyid[contacts.geom2]
        # the object against a hand body: not the object on the table (the world body), not the hand on it
        hand_object = ((body1 == s.object_body) | (body2 == s.object_body)) & (body1 != body2) & (body1 != 0) & (body2 != 0)
        return max(0.0, float(-contacts.dist[hand_object].min())) if hand_object.any() else 0.0

    def _close(self, start: np.ndarray, target: np.ndarray) -> None:
        """Ramp the finger targets from ``start`` to ``target`` over the close phase."""
        import mujoco

        m, d = self.scene.model, self.scene.data
        step, change = mujoco.mj_step, target - start
        for steps, close_fraction, _ in self.schedule[: len(self.close_chunks)]:
            d.ctrl[:] = start + change * close_fraction
            step(m, d, nstep=steps)

    def _unstable(self) -> bool:
        import mujoco

        d = self.scene.data
        return bool(d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0 or not np.isfinite(d.qpos).all())

    def _object_lost(self) -> bool:
        """True if the object can never touch the hand again.

        It lies wholly below a sphere about the palm that holds the hand in any joint
        configuration and falls faster than the palm rises; it then free-falls at g while
        the palm holds still or follows the smooth lift profile, never accelerating
        downward faster than that profile allows (far below g), so the gap only grows.
        Valid in every phase, so it is checked before each control chunk.
        """
        s, up = self.scene, self.scene.up
        if up is not None:  # on a table: heights and velocities along its normal
            object_top = float(self._object_com @ up) + s.object_radius_m
            hand_bottom = float(self._palm_origin @ up) - s.hand_reach_m
            return bool(object_top < hand_bottom and self._object_linvel @ up < self._palm_linvel @ up)
        object_top = self._object_com[2] + s.object_radius_m
        hand_bottom = self._palm_origin[2] - s.hand_reach_m
        return bool(object_top < hand_bottom and self._object_linvel[2] < self._palm_linvel[2])

    def _settled(self, recent, worst_t: float, worst_r: float, seconds_left: float) -> bool:
        """Record the object's speed and turn rate now; True once the window is full (after twice its length) and even
        ``six_dir_settle_factor`` times the window's fastest rates for ``seconds_left`` keep it within the limits."""
        cfg = self.config
        linear, angular = self._object_linvel, self._object_qvel[3:]
        recent.append((_length(linear), math.degrees(_length(angular))))
        recent_full = len(recent) == recent.maxlen
        if not recent_full or seconds_left > cfg.six_dir_duration_s - 2 * cfg.six_dir_settle_s:
            return False
        speed = max(v for v, _ in recent) * cfg.six_dir_settle_factor
        rate = max(w for _, w in recent) * cfg.six_dir_settle_factor
        return worst_t + speed * seconds_left < cfg.six_dir_max_translation_m and worst_r + rate * seconds_left < cfg.six_dir_max_rotation_deg

    def _ballistic_z(self, remaining_steps: int) -> float:
        """Object COM height after ``remaining_steps`` of free fall, by MuJoCo's semi-implicit Euler update."""
        import mujoco

        s, d = self.scene, self.scene.data
        h, n = self.config.timestep_s, remaining_steps
        velocity = np.zeros(6)  # [angular, linear] at the centre of mass, world axes
        mujoco.mj_objectVelocity(s.model, d, mujoco.mjtObj.mjOBJ_BODY, s.object_body, velocity, 0)
        return float(d.xipos[s.object_body, 2] + h * n * velocity[5] - GRAVITY_MPS2 * h * h * n * (n + 1) / 2)

    def lift(self, pose: np.ndarray, quat: np.ndarray, target: np.ndarray) -> tuple[float, str]:
        """Lift ratio dz_object / dz_hand and failure reason ('' on success) of one grasp.

        dz_hand is the commanded rise of the kinematically driven palm (``lift_height_m``);
        the welded palm tracks it to within 0.1 mm (measured: 0.04 mm at the top).
        """
        import mujoco

        cfg, s, m, d = self.config, self.scene, self.scene.model, self.scene.data
        if s.up is not None:
            return self._lift_from_table(pose, quat, target)
        self._reset(pose, quat)
        object_z0 = float(d.xipos[s.object_body, 2])
        palm_z0 = float(d.mocap_pos[0, 2])
        start = d.ctrl.copy()
        step, change, lost, mocap = mujoco.mj_step, target - start, self._object_lost, d.mocap_pos[0]
        steps_done = 0
        for (steps, close_fraction, _), rise in zip(self.schedule, self._rises):
            if lost():
                object_z = self._ballistic_z(self.total_steps - steps_done)
                break
            if close_fraction is not None:
                d.ctrl[:] = start + change * close_fraction
            if rise is not None:
                mocap[2] = palm_z0 + rise
            step(m, d, nstep=steps)
            steps_done += steps
        else:
            object_z = float(d.xipos[s.object_body, 2])
        if self._unstable():
            return float("nan"), "simulation_unstable"
        ratio = (object_z - object_z0) / cfg.lift_height_m
        return ratio, ("" if ratio > cfg.success_lift_ratio else "dropped")

    def _lift_from_table(self, pose: np.ndarray, quat: np.ndarray, target: np.ndarray) -> tuple[float, str]:
        """``lift`` on a table: the object starts resting on it, the palm rises along its normal ``up``.

        An object that has left the hand lands back on the table: its ratio is then 0 (a drop).
        """
        import mujoco

        cfg, s, m, d = self.config, self.scene, self.scene.model, self.scene.data
        self._reset(pose, quat)
        object_z0 = float(d.xipos[s.object_body] @ s.up)
        palm0 = d.mocap_pos[0].copy()
        start = d.ctrl.copy()
        step, change, lost, mocap = mujoco.mj_step, target - start, self._object_lost, d.mocap_pos[0]
        for (steps, close_fraction, _), rise in zip(self.schedule, self._rises):
            if lost():
                object_z = object_z0
                break
            if close_fraction is not None:
                d.ctrl[:] = start + change * close_fraction
            if rise is not None:
                mocap[:] = palm0 + s.up * rise
            step(m, d, nstep=steps)
        else:
            object_z = float(d.xipos[s.object_body] @ s.up)
        if self._unstable():
            return float("nan"), "simulation_unstable"
        ratio = (object_z - object_z0) / cfg.lift_height_m
        return ratio, ("" if ratio > cfg.success_lift_ratio else "dropped")

    def six_directions(self, pose: np.ndarray, quat: np.ndarray, target: np.ndarray, stop_at_failure: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Per direction (6,), the object's largest translation (m) and rotation (deg) under the force.

        A direction stops early once either limit is exceeded (it has failed), or once the object has
        settled (``six_dir_settle_factor``: so slow over the last ``six_dir_settle_s`` that even several times
        faster it could not reach a limit in the time left; it has passed); the values are then those at that moment. ``stop_at_failure``: no direction after a failed one is
        pushed (its values stay NaN): the grasp has failed the test.
        """
        import mujoco

        cfg, s, m, d = self.config, self.scene, self.scene.model, self.scene.data
        translation = np.full(6, np.nan)
        rotation = np.full(6, np.nan)
        gravity = m.opt.gravity.copy()
        m.opt.gravity[:] = 0.0
        table = s.table_geom
        if table >= 0:  # the grip alone: no table to prop the object up (restored below)
            table_collision = int(m.geom_contype[table]), int(m.geom_conaffinity[table])
            m.geom_contype[table] = m.geom_conaffinity[table] = 0
        try:
            self._reset(pose, quat)
            com0 = d.xipos[s.object_body].copy()
            self._close(d.ctrl.copy(), target)
            spec = mujoco.mjtState.mjSTATE_INTEGRATION
            closed = np.empty(mujoco.mj_stateSize(m, spec))
            mujoco.mj_getState(m, d, closed, spec)
            force = cfg.six_dir_force_per_kg_n * cfg.object_mass_kg
            step, com, object_qpos = mujoco.mj_step, self._object_com, self._object_qpos
            max_t, max_r = cfg.six_dir_max_translation_m, cfg.six_dir_max_rotation_deg
            for k, direction in enumerate(DIRECTION_VECTORS):
                mujoco.mj_setState(m, d, closed, spec)
                d.xfrc_applied[:] = 0.0
                d.xfrc_applied[s.object_body, :3] = force * direction
                worst_t = worst_r = 0.0
                recent = collections.deque(maxlen=self.settle_chunks)  # (speed m/s, turn rate deg/s) at the last chunks' ends
                remaining = sum(self.six_dir_chunks)
                for steps in self.six_dir_chunks:
                    step(m, d, nstep=steps)
                    remaining -= steps
                    worst_t = max(worst_t, _length(com - com0))
                    qw = min(1.0, abs(float(object_qpos[3])))
                    worst_r = max(worst_r, math.degrees(2.0 * math.acos(qw)))
                    if worst_t >= max_t or worst_r >= max_r:
                        break
                    if self.settle_chunks and self._settled(recent, worst_t, worst_r, remaining * cfg.timestep_s):
                        break  # settled: passes this direction
                translation[k], rotation[k] = worst_t, worst_r
                if stop_at_failure and (worst_t >= cfg.six_dir_max_translation_m or worst_r >= cfg.six_dir_max_rotation_deg):
                    break
            d.xfrc_applied[:] = 0.0
        finally:
            m.opt.gravity[:] = gravity
            if table >= 0:
                m.geom_contype[table], m.geom_conaffinity[table] = table_collision
        return translation, rotation
