"""The lift test's MuJoCo scene for a hand from its MJCF (``hand.described.DescribedHand``), beside the Shadow Hand's.

The scene is the Shadow Hand's (``sim.scene``) with the described hand in it, built with MuJoCo's model editing API
(``MjSpec``) from the hand's own file, so its ``<default>`` classes, meshes, joint damping and collision filters are
MuJoCo's reading of that file:

- the root link gets a free joint welded to a mocap body (the palm target), every hand body gravity compensation;
- the hand's visual geoms (neither ``contype`` nor ``conaffinity``) and the colliding geoms its description left out
  are removed, every body keeping the mass and inertia the full file gives it (written as explicit inertials);
  keyframes, sensors, tendons and the file's own actuators are removed;
- every geom's contact parameters (solref, solimp, solmix, margin, gap, priority: the hand's, the object's and the
  table's) are MuJoCo's defaults, as in the Shadow Hand's scene, and the object's free joint has no damping or friction
  loss: contact softness is part of the protocol, like friction, and the object and the table must not inherit the
  hand file's ``<default>`` class. LEAP's file makes every geom of its main class almost rigid (solref 0.1 ms, solimp
  0.999) and damps every joint, which at the 2 ms step throws objects out of grasps (on four household objects: 4 of
  the same 64 grasps held with its values, 17 with the defaults, none thrown);
- one position actuator per joint, in joint order (the lift test drives ``ctrl`` with a stored pose's joints), every
  one with the lift config's gain ``finger_kp`` (5 N·m/rad), as the Shadow Hand's: the gain is the protocol's closing
  stiffness, not a property of the hand (Menagerie's Allegro file says 1 N·m/rad, LEAP's 3, the gym Shadow Hand's 1; at
  1 N·m/rad Allegro's grasps that hold at 5 slip: 11 against 30 of the same 64 grasps held on four household objects).
  The file's own servo keeps its damping kv and force limit, which are the hand's;
- the object, the table, gravity, friction, contact dimension, elliptic cones and the time step exactly as
  ``sim.scene.scene_mjcf`` sets them; the object and the table collide with every collision bit the hand's geoms use.

Lengths in metres, angles in radians, gains in N·m/rad.
"""

from __future__ import annotations

import functools
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dexlite_pipeline.hand.described import DescribedHand
from dexlite_pipeline.sim.config import LiftConfig
from dexlite_pipeline.sim.scene import GRAVITY_MPS2, OBJECT_BODY, PALM_TARGET_BODY, TABLE_GEOM, NO_PIECES, LiftScene, SceneBuildError


@dataclass(frozen=True)
class HandDrive:
    """Per joint (J,) of a described hand, its own position servo in the file: gain (NaN: none; recorded, not used: the
    lift test closes with ``finger_kp``), damping (N·m·s/rad) and force limit (N·m, inf: unlimited)."""

    kp: np.ndarray
    kv: np.ndarray
    force_limit: np.ndarray

    def gains(self, config: LiftConfig) -> np.ndarray:
        """(J,) the gain of each joint's servo in the lift test: the protocol's ``finger_kp`` for every joint (N·m/rad)."""
        return np.full(len(self.kp), config.finger_kp)


def hand_drive(hand: DescribedHand) -> HandDrive:
    """The hand's own position servos, read from its compiled file (``Joint.kp`` and the actuators' kv and force range)."""
    import mujoco

    model = hand.description.mj_model()
    count = len(hand.joint_names)
    kp, kv, limit = np.full(count, np.nan), np.zeros(count), np.full(count, np.inf)
    for j, joint in enumerate(hand.description.joints):
        if joint.kp is None:
            continue
        a = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, joint.actuator)
        kp[j], kv[j] = joint.kp, -float(model.actuator_biasprm[a, 2])
        if model.actuator_forcelimited[a]:
            limit[j] = float(np.abs(model.actuator_forcerange[a]).max())
    return HandDrive(kp, kv, limit)


_BASE_LOCK = threading.Lock()


def _default_contact(geom) -> None:
    """Give an ``MjSpec`` geom MuJoCo's default contact parameters (solref, solimp, solmix, margin, gap, priority)."""
    import mujoco

    default = mujoco.MjSpec().worldbody.add_geom()
    geom.solref, geom.solimp, geom.solmix = default.solref.copy(), default.solimp.copy(), default.solmix
    geom.margin, geom.gap, geom.priority = default.margin, default.gap, default.priority


@functools.lru_cache(maxsize=4)
def _hand_base(hand: DescribedHand):
    """The hand part of every scene of ``hand`` (module docstring), built once per hand, and the collision bits its kept
    geoms use. Geoms and bodies are matched to the full file's compiled ids (``id`` after a compile of the same spec)."""
    import mujoco

    d = hand.description
    spec = mujoco.MjSpec.from_file(d.xml_path) if d.xml_path is not None else mujoco.MjSpec.from_string(d.xml_string)
    full = spec.compile()
    spec.modelname = "lift_scene"
    for element in list(spec.keys) + list(spec.sensors) + list(spec.actuators) + list(spec.tendons):
        spec.delete(element)
    for body in spec.bodies:  # the full file's inertials, before any geom goes
        b = body.id
        if b <= 0:  # the world
            continue
        body.explicitinertial = True
        body.mass = float(full.body_mass[b])
        body.ipos = full.body_ipos[b].copy()
        body.iquat = full.body_iquat[b].copy()
        body.inertia = full.body_inertia[b].copy()
        body.gravcomp = 1.0
    kept = {shape.geom for shape in d.shapes}
    bits = 0
    gone = []
    for geom in spec.geoms:  # ids are the compiled ones until the first deletion
        if geom.id in kept:
            bits |= int(full.geom_contype[geom.id]) | int(full.geom_conaffinity[geom.id])
        else:
            gone.append(geom)
    for geom in gone:
        spec.delete(geom)
    for geom in spec.geoms:
        _default_contact(geom)
    used_meshes = {geom.meshname for geom in spec.geoms if geom.type == mujoco.mjtGeom.mjGEOM_MESH}
    for mesh in list(spec.meshes):
        if mesh.name not in used_meshes:
            spec.delete(mesh)
    next(body for body in spec.bodies if body.name == hand.root_link).add_freejoint()
    return spec, bits


def described_scene_spec(hand: DescribedHand, convex_paths: list[Path], scale: float, config: LiftConfig, table=None):
    """The scene (module docstring) as an ``mujoco.MjSpec``: the hand, the palm target, the object of ``convex_paths``
    at ``scale``, and on a table (``objects.rest_pose.SupportPlane``) the table with gravity along its downward normal."""
    import mujoco

    if not convex_paths:
        raise SceneBuildError(NO_PIECES)
    with _BASE_LOCK:  # the lift test's worker threads share the cached hand part: one copies it at a time
        base, bits = _hand_base(hand)
        spec = base.copy()

    option = spec.option
    option.timestep = config.timestep_s
    option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    option.impratio = config.impratio
    option.gravity = [0.0, 0.0, -GRAVITY_MPS2] if table is None else [-GRAVITY_MPS2 * float(v) for v in table.normal]
    option.jacobian = mujoco.mjtJacobian.mjJAC_SPARSE
    option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_ISLAND)

    world = spec.worldbody
    world.add_body(name=PALM_TARGET_BODY, mocap=True)
    collide = bits | 1
    if table is not None:
        normal = np.asarray(table.normal, dtype=np.float64)
        quat = np.zeros(4)
        mujoco.mju_quatZ2Vec(quat, normal)
        plane = world.add_geom(name=TABLE_GEOM, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, 1.0], pos=-table.offset_m(scale) * normal,
                       quat=quat, contype=collide, conaffinity=collide, condim=config.contact_condim,
                       friction=[config.friction, 0.005, 0.0001])
        _default_contact(plane)
    obj = world.add_body(name=OBJECT_BODY)
    free = obj.add_freejoint(name="object_free")
    free.damping, free.frictionloss, free.armature = np.zeros(3), 0.0, 0.0  # not the hand file's joint defaults
    for i, path in enumerate(convex_paths):
        name = f"object_piece_{i:03d}"
        spec.add_mesh(name=name, file=str(Path(path).resolve()), scale=[float(scale)] * 3)
        piece = obj.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name, contype=collide, conaffinity=collide,
                     condim=config.contact_condim, friction=[config.friction, 0.005, 0.0001], group=3)
        _default_contact(piece)
    spec.add_equality(type=mujoco.mjtEq.mjEQ_WELD, objtype=mujoco.mjtObj.mjOBJ_BODY, name="palm_weld", name1=PALM_TARGET_BODY,
                      name2=hand.root_link, data=[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0])
    drive = hand_drive(hand)
    gains = drive.gains(config)
    for j, joint in enumerate(hand.joint_names):
        actuator = spec.add_actuator(name=f"A_{joint}", target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        actuator.set_to_position(kp=float(gains[j]), kv=float(drive.kv[j]), inheritrange=1.0)
        actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        if np.isfinite(drive.force_limit[j]):
            actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            actuator.forcerange = [-float(drive.force_limit[j]), float(drive.force_limit[j])]
    return spec


@dataclass
class DescribedLiftScene(LiftScene):
    """``LiftScene`` of a described hand: ``configure`` writes the lift test's gains (``HandDrive.gains``)."""

    drive: HandDrive | None = None

    @classmethod
    def build_for(cls, hand: DescribedHand, convex_paths: list[Path], scale: float, config: LiftConfig, table=None) -> "DescribedLiftScene":
        """Compile ``described_scene_spec`` and index it like ``LiftScene.build``; ``SceneBuildError`` if MuJoCo cannot."""
        spec = described_scene_spec(hand, convex_paths, scale, config, table)
        try:
            model = spec.compile()
        except ValueError as exc:
            raise SceneBuildError(f"MuJoCo could not compile the scene: {str(exc).splitlines()[0]}") from exc
        return cls.from_model(model, config, table, hand.root_link, hand.joint_names, drive=hand_drive(hand))

    def configure(self, config: LiftConfig) -> None:
        """``LiftScene.configure``, then each actuator's gain (``HandDrive.gains``)."""
        super().configure(config)
        if self.drive is not None:
            kp = self.drive.gains(config)
            self.model.actuator_gainprm[:, 0] = kp
            self.model.actuator_biasprm[:, 1] = -kp


__all__ = ["DescribedLiftScene", "HandDrive", "described_scene_spec", "hand_drive"]
