"""The MuJoCo scene of the lift test: one object (its convex pieces) and the palm-rooted Shadow Hand.

One model is compiled per (object, scale) and reused for all of that object's grasps;
friction, object mass and finger gains are written into the compiled model in place
(``LiftScene.configure``), so a config change never needs a recompile.

Choices that move measured success rates (docs/design.md, "Physics tests"):
- the palm is a free body welded to a mocap body (a body hung directly under a mocap
  body has no velocity, so friction could not act on it);
- gravity compensation on every hand body, so the weld and the finger actuators carry
  only the object;
- 22 independent position actuators (no tendons: DexGraspNet's grasps break the real
  hand's J0/J1 coupling), force limits from the gym model (J0 shares J1's motor);
- elliptic friction cones with impratio 10, 2 ms steps (sparse Jacobians: speed only);
- the world frame is the object frame, so gravity acts along the object's -z; on a table
  (tabletop mode) the scene adds the table, a plane in the object frame below the object's
  resting pose (``objects.rest_pose.SupportPlane``), and gravity acts along its downward normal,
  the world's -z in the resting pose.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dexlite_pipeline.hand.mjcf import PALM_BODY, gym_hand_asset_dir, hand_mjcf
from dexlite_pipeline.hand.model import JOINT_NAMES
from dexlite_pipeline.sim.config import LiftConfig

OBJECT_BODY = "object"
TABLE_GEOM = "table"
PALM_TARGET_BODY = "palm_target"
VISUAL_CLASS = "robot0:D_Vizual"
GRAVITY_MPS2 = 9.81


class SceneBuildError(ValueError):
    """An object whose scene cannot be built (no convex pieces, MuJoCo compile error)."""


# An asset without convex pieces: CoACD gave none, or it was prepared for training only (objects.dataset_collision false).
NO_PIECES = "object has no convex pieces to collide (an object prepared without them, objects.dataset_collision false, is trained on only)"


@functools.cache
def _actuator_force_limits() -> dict[str, float]:
    """Finger torque limits (N·m) of the gym model's actuators; J0 shares J1's (one motor drives both)."""
    robot = ET.parse(gym_hand_asset_dir() / "hand" / "shared.xml").getroot()
    limits = {}
    for act in robot.iter("position"):
        joint = act.get("joint")
        if joint and act.get("forcerange"):
            limits[joint] = float(act.get("forcerange").split()[1])
    for name in JOINT_NAMES:
        if name not in limits and name.endswith("J0") and name.replace("J0", "J1") in limits:
            limits[name] = limits[name.replace("J0", "J1")]
    missing = [n for n in JOINT_NAMES if n not in limits]
    if missing:
        raise RuntimeError(f"no actuator force limit for {', '.join(missing)} in the gym hand model")
    return limits


def _strip_visuals(root: ET.Element) -> None:
    """Drop the visual meshes: never rendered here, and each costs kinematics work per step."""
    for parent in root.iter():
        for child in list(parent):
            if child.tag == "geom" and child.get("class") == VISUAL_CLASS:
                parent.remove(child)
    asset = root.find("asset")
    for mesh in list(asset.findall("mesh")):
        asset.remove(mesh)


def scene_mjcf(convex_paths: list[Path], scale: float, config: LiftConfig, table=None) -> str:
    """MJCF text of the scene: hand + mocap target + free object made of ``convex_paths`` scaled by ``scale``.

    ``table`` (an ``objects.rest_pose.SupportPlane``; tabletop mode): adds the table plane at this scale and
    turns gravity along its downward normal. None: no table, gravity along -z (floating mode).
    """
    if not convex_paths:
        raise SceneBuildError(NO_PIECES)
    root = hand_mjcf(free_root=True, model_name="lift_scene")
    _strip_visuals(root)
    option = ET.Element(
        "option",
        timestep=repr(config.timestep_s),
        cone="elliptic",
        impratio=repr(config.impratio),
        gravity=f"0 0 {-GRAVITY_MPS2}" if table is None else " ".join(repr(-GRAVITY_MPS2 * float(v)) for v in table.normal),
        # Sparse constraint Jacobians: ~27% less time per step here than MuJoCo's dense
        # choice for small models, with results equal to 1e-10 (measured on real grasps).
        jacobian="sparse",
    )
    # No constraint islands: the hand (welded to the world) and the object it touches form
    # one island, so discovering islands every step is pure overhead (~3% of a step). On
    # the 494 DexGraspNet sample grasps 490 lift ratios are bit-identical and 4 differ by
    # rounding (< 3e-5); no outcome changes.
    ET.SubElement(option, "flag", island="disable")
    root.insert(1, option)
    asset = root.find("asset")
    worldbody = root.find("worldbody")
    for body in worldbody.iter("body"):
        body.set("gravcomp", "1")
    ET.SubElement(worldbody, "body", name=PALM_TARGET_BODY, mocap="true")
    if table is not None:
        normal = np.asarray(table.normal, dtype=np.float64)
        ET.SubElement(
            worldbody,
            "geom",
            name=TABLE_GEOM,
            type="plane",
            size="0 0 1",
            pos=" ".join(repr(float(v)) for v in -table.offset_m(scale) * normal),
            zaxis=" ".join(repr(float(v)) for v in normal),
            contype="1",
            conaffinity="1",
            condim=str(config.contact_condim),
            friction=f"{config.friction} 0.005 0.0001",
        )
    obj = ET.SubElement(worldbody, "body", name=OBJECT_BODY)
    ET.SubElement(obj, "freejoint", name="object_free")
    s = repr(float(scale))
    for i, path in enumerate(convex_paths):
        ET.SubElement(asset, "mesh", name=f"object_piece_{i:03d}", file=str(Path(path).resolve()), scale=f"{s} {s} {s}")
        ET.SubElement(
            obj,
            "geom",
            name=f"object_piece_{i:03d}",
            type="mesh",
            mesh=f"object_piece_{i:03d}",
            contype="1",
            conaffinity="1",
            condim=str(config.contact_condim),
            friction=f"{config.friction} 0.005 0.0001",
            group="3",
        )
    equality = ET.SubElement(root, "equality")
    ET.SubElement(equality, "weld", name="palm_weld", body1=PALM_TARGET_BODY, body2=PALM_BODY, relpose="0 0 0 1 0 0 0")
    actuator = ET.SubElement(root, "actuator")
    limits = _actuator_force_limits()
    for name in JOINT_NAMES:
        ET.SubElement(
            actuator,
            "position",
            name=f"A_{name}",
            joint=name,
            kp=repr(config.finger_kp),
            ctrllimited="true",
            inheritrange="1",
            forcelimited="true",
            forcerange=f"{-limits[name]} {limits[name]}",
        )
    return ET.tostring(root, encoding="unicode")


def _reach_from(model, geoms: np.ndarray, root_body: int) -> float:
    """Bound on the distance from ``root_body``'s origin to any point of ``geoms``, whatever the joint angles.

    Hinges sit at body origins, so by the triangle inequality a geom's points lie within
    the sum of its ancestors' offsets, its own offset and its bounding radius.
    """
    reach = 0.0
    for g in geoms:
        body = int(model.geom_bodyid[g])
        chain = 0.0
        while body != root_body:
            chain += float(np.linalg.norm(model.body_pos[body]))
            body = int(model.body_parentid[body])
        reach = max(reach, chain + float(np.linalg.norm(model.geom_pos[g])) + float(model.geom_rbound[g]))
    return reach


@dataclass
class LiftScene:
    """A compiled scene plus the indices the test needs; ``configure`` writes the physical constants in place."""

    model: object  # mujoco.MjModel
    data: object  # mujoco.MjData
    object_body: int
    palm_body: int
    object_qpos: slice  # free joint of the object: pos (3) + quat (4)
    palm_qpos: slice
    joint_qpos: slice
    object_qvel: slice
    palm_qvel: slice
    hand_geoms: np.ndarray
    object_geoms: np.ndarray
    compiled_mass_kg: float
    compiled_inertia: np.ndarray
    hand_reach_m: float  # radius about the palm origin holding the hand's collision shapes in any joint configuration
    object_radius_m: float  # radius about the object's centre of mass holding its pieces
    up: np.ndarray | None = None  # the table's upward unit normal (tabletop mode); None: floating, up is +z
    table_geom: int = -1  # the table's geom id (tabletop mode), -1 without a table

    @classmethod
    def build(cls, convex_paths: list[Path], scale: float, config: LiftConfig, table=None) -> "LiftScene":
        import mujoco

        xml = scene_mjcf(convex_paths, scale, config, table)
        try:
            model = mujoco.MjModel.from_xml_string(xml)
        except ValueError as exc:
            raise SceneBuildError(f"MuJoCo could not compile the scene: {str(exc).splitlines()[0]}") from exc
        return cls.from_model(model, config, table, PALM_BODY, JOINT_NAMES)

    @classmethod
    def from_model(cls, model, config: LiftConfig, table, palm_body_name: str, joint_names, **fields) -> "LiftScene":
        """The scene of a compiled model whose hand is rooted at ``palm_body_name`` (with a free joint), its finger
        joints ``joint_names`` consecutive in qpos and driven by the actuators in that order; ``fields``: a subclass's own."""
        import mujoco

        data = mujoco.MjData(model)
        object_body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, OBJECT_BODY)
        palm_body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, palm_body_name)
        palm_jnt = int(model.body_jntadr[palm_body])
        palm_adr = int(model.jnt_qposadr[palm_jnt])
        obj_jnt = int(model.body_jntadr[object_body])
        obj_adr = int(model.jnt_qposadr[obj_jnt])
        first_finger = int(model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint_names[0])])
        geom_body = np.asarray(model.geom_bodyid)
        collides = (np.asarray(model.geom_contype) > 0) | (np.asarray(model.geom_conaffinity) > 0)
        hand_geoms = np.flatnonzero(collides & (geom_body != object_body) & (geom_body > 0))
        table_geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, TABLE_GEOM) if table is not None else -1
        object_geoms = np.flatnonzero(geom_body == object_body)
        scene = cls(
            model=model,
            data=data,
            object_body=object_body,
            palm_body=palm_body,
            object_qpos=slice(obj_adr, obj_adr + 7),
            palm_qpos=slice(palm_adr, palm_adr + 7),
            joint_qpos=slice(first_finger, first_finger + len(joint_names)),
            object_qvel=slice(int(model.jnt_dofadr[obj_jnt]), int(model.jnt_dofadr[obj_jnt]) + 6),
            palm_qvel=slice(int(model.jnt_dofadr[palm_jnt]), int(model.jnt_dofadr[palm_jnt]) + 6),
            hand_geoms=hand_geoms,
            object_geoms=object_geoms,
            compiled_mass_kg=float(model.body_mass[object_body]),
            compiled_inertia=np.array(model.body_inertia[object_body]),
            hand_reach_m=_reach_from(model, hand_geoms, palm_body),
            object_radius_m=float((np.linalg.norm(model.geom_pos[object_geoms] - model.body_ipos[object_body], axis=1) + model.geom_rbound[object_geoms]).max()),
            up=None if table is None else np.asarray(table.normal, dtype=np.float64),
            table_geom=table_geom,
            **fields,
        )
        scene.configure(config)
        return scene

    def configure(self, config: LiftConfig) -> None:
        """Write friction, object mass (inertia scaled alike), finger gains and contact/solver options into the model."""
        m = self.model
        import mujoco

        m.opt.timestep = config.timestep_s
        m.opt.impratio = config.impratio
        multi_ccd_off = int(mujoco.mjtDisableBit.mjDSBL_MULTICCD)
        m.opt.disableflags = (m.opt.disableflags & ~multi_ccd_off) | (0 if config.multi_contact else multi_ccd_off)
        m.geom_friction[self.hand_geoms, 0] = config.friction
        m.geom_friction[self.object_geoms, 0] = config.friction
        if self.table_geom >= 0:
            m.geom_friction[self.table_geom, 0] = config.friction
            m.geom_condim[self.table_geom] = config.contact_condim
        m.geom_condim[self.object_geoms] = config.contact_condim  # a contact takes the larger condim of its two geoms
        m.body_mass[self.object_body] = config.object_mass_kg
        m.body_inertia[self.object_body] = self.compiled_inertia * (config.object_mass_kg / self.compiled_mass_kg)
        # Position actuator: force = kp * (ctrl - q), i.e. gain kp and bias [0, -kp, 0].
        m.actuator_gainprm[:, 0] = config.finger_kp
        m.actuator_biasprm[:, 1] = -config.finger_kp
