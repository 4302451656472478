"""A hand as data: everything the pipeline needs to know about a hand, read from its MJCF.

``hand_description("shadow" | "allegro" | "leap" | path)`` compiles the MJCF with MuJoCo and
returns a ``HandDescription``: the links and their tree, the joints in qpos order with limits
(rad) and position gains, the collision shapes with surface samples, contact candidates on
the finger pads and the palm, the palm frame with its approach direction, and an open
pre-grasp (how each is derived: ``hand.derive`` and ``docs/hands.md``). Lengths are metres,
angles radians; points and directions are in their link's (body's) frame, the palm frame in
the root body's frame.

The Shadow Hand is the palm-rooted model ``hand.mjcf`` builds from gymnasium-robotics, Allegro
and LEAP the Menagerie files shipped in ``data/hands/``; a path names any MJCF file.
``hand.described.DescribedHand`` makes a description the hand model the energies, optimization from
scratch and the lift test take from Python; the stages still use ``hand.model``'s ``ShadowHand``,
unchanged. A file that cannot be used raises ``HandDescriptionError`` with a one-line reason.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dexlite_pipeline.hand import derive
from dexlite_pipeline.hand.chain import ChainError, body_names, check_tree, pk_chain_from_model
from dexlite_pipeline.hand.shapes import KINDS, fitted_box, signed_distance, surface_samples

HANDS_DIR = Path(__file__).resolve().parent.parent / "data" / "hands"
SHIPPED_HANDS = ("allegro", "leap")  # folders of data/hands/, each with right_hand.xml
HAND_NAMES = ("shadow",) + SHIPPED_HANDS
SURFACE_SPACING_M = 0.002  # surface samples of collision shapes, about this far apart
CONTACTS_PER_LINK = 10
PALM_CONTACTS = 20


class HandDescriptionError(ValueError):
    """An MJCF that cannot describe a hand; the message is one line saying why."""


@dataclass(frozen=True)
class Joint:
    """One hinge joint: its name, the link it turns, limits (rad), axis (link frame) and actuator."""

    name: str
    link: str
    lower: float
    upper: float
    axis: tuple[float, float, float]
    actuator: str | None  # the actuator driving it, if the MJCF has one
    kp: float | None  # that actuator's position gain (N·m/rad) when it is a position servo


@dataclass(frozen=True)
class CollisionShape:
    """One collision geom of the MJCF on its link: kind, MuJoCo size (m), pose in the link frame, surface samples.

    kind: sphere, capsule (radius, half length; along z), ellipsoid, cylinder, box (half extents) or
    mesh; for a mesh, ``box_centre`` and ``box_half`` are a box fitted to it in the geom frame.
    points/normals: surface samples about ``SURFACE_SPACING_M`` apart, in the link frame (P, 3).
    """

    name: str  # the geom's name, ``geom<id>`` when it has none
    geom: int  # its id in the compiled model
    link: str
    kind: str
    size: tuple[float, float, float]
    pos: tuple[float, float, float]
    quat: tuple[float, float, float, float]  # (w, x, y, z)
    points: np.ndarray
    normals: np.ndarray
    box_centre: tuple[float, float, float] | None = None
    box_half: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class HandDescription:
    """A hand read from its MJCF (see the module doc); every array is float64."""

    name: str
    source: str  # the MJCF file, or how the Shadow Hand's was built
    links: tuple[str, ...]  # bodies below the world, MuJoCo's order (parents first); links[0] is the root
    parents: tuple[int, ...]  # index of each link's parent, -1 for the root
    joints: tuple[Joint, ...]  # qpos order
    shapes: tuple[CollisionShape, ...]
    left_out_geoms: tuple[str, ...]  # geoms that can collide but sit in a group of visual geoms
    fingers: tuple[tuple[str, ...], ...]  # each finger's links, from the root's child to the leaf
    opposing: tuple[str, ...]  # the leaf link of each finger that opposes the others (a thumb): no vote on the palm normal
    contact_links: tuple[str, ...]
    contact_points: np.ndarray  # (C, 3) candidates, each in its link's frame
    contact_normals: np.ndarray  # (C, 3) outward surface normals there
    contact_link: np.ndarray  # (C,) index into ``links``
    palm_frame: np.ndarray  # (4, 4) in the root link's frame: z the approach direction, x along the fingers
    pregrasp: np.ndarray  # (J,) open pre-grasp joint vector (rad)
    xml_path: str | None = None  # compile from this file ...
    xml_string: str | None = None  # ... or from this text (the Shadow Hand: absolute mesh paths)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    @property
    def joint_limits(self) -> np.ndarray:
        """(J, 2) lower and upper limit of each joint (rad)."""
        return np.array([[j.lower, j.upper] for j in self.joints])

    @property
    def approach(self) -> np.ndarray:
        """(3,) unit direction the palm faces (moves along to reach an object), root link frame."""
        return self.palm_frame[:3, 2].copy()

    def candidates_per_link(self) -> dict[str, int]:
        """Link name -> number of contact candidates on it (links with candidates only)."""
        counts = np.bincount(self.contact_link, minlength=len(self.links))
        return {self.links[i]: int(c) for i, c in enumerate(counts) if c}

    def mj_model(self):
        """The compiled ``mujoco.MjModel`` of the same file."""
        import mujoco

        if self.xml_path is not None:
            return mujoco.MjModel.from_xml_path(self.xml_path)
        return mujoco.MjModel.from_xml_string(self.xml_string)

    def chain(self, dtype=None, device="cpu"):
        """The pytorch-kinematics chain of the hand (``hand.chain``): frames are the bodies' world poses in the file."""
        import torch

        return pk_chain_from_model(self.mj_model(), dtype=dtype or torch.float64, device=device)


def _compile(path: Path | None, text: str):
    import mujoco

    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise HandDescriptionError(f"not XML ({exc})") from None
    if root.tag != "mujoco":
        raise HandDescriptionError(f"not an MJCF file: its root element is <{root.tag}>, not <mujoco>")
    try:
        return mujoco.MjModel.from_xml_path(str(path)) if path is not None else mujoco.MjModel.from_xml_string(text)
    except ValueError as exc:
        reason = " ".join(str(exc).split())
        raise HandDescriptionError(f"MuJoCo cannot compile it: {reason}") from None


def collision_geoms(model) -> tuple[list[int], list[int]]:
    """The geoms used as collision shapes, and the colliding geoms left out.

    A geom collides when its contype or conaffinity is set. When some geom group holds only
    colliding geoms (a dedicated collision group, as Allegro's 3 or the Shadow Hand's 4), a
    colliding geom in a group that also holds visual geoms is left out: the Shadow Hand's two
    1 mm placeholder boxes in its visual group 1, for instance.
    """
    colliding = [g for g in range(model.ngeom) if model.geom_contype[g] or model.geom_conaffinity[g]]
    groups = {int(model.geom_group[g]) for g in range(model.ngeom)}
    mixed = {grp for grp in groups if any(int(model.geom_group[g]) == grp and not (model.geom_contype[g] or model.geom_conaffinity[g]) for g in range(model.ngeom))}
    if not any(grp not in mixed for grp in groups):
        return colliding, []
    return [g for g in colliding if int(model.geom_group[g]) not in mixed], [g for g in colliding if int(model.geom_group[g]) in mixed]


def _shape(model, g: int, links: tuple[str, ...]) -> CollisionShape:
    kind = KINDS.get(int(model.geom_type[g]))
    name = model.geom(g).name or f"geom{g}"
    if kind is None:
        raise HandDescriptionError(f"collision geom {name} has a type ({int(model.geom_type[g])}) that is not a solid a hand can have")
    mesh, box_centre, box_half = None, None, None
    if kind == "mesh":
        m = int(model.geom_dataid[g])
        vertices = model.mesh_vert[model.mesh_vertadr[m] : model.mesh_vertadr[m] + model.mesh_vertnum[m]].astype(np.float64)
        faces = model.mesh_face[model.mesh_faceadr[m] : model.mesh_faceadr[m] + model.mesh_facenum[m]]
        mesh = (vertices, faces)
        centre, half = fitted_box(vertices)
        box_centre, box_half = tuple(centre.tolist()), tuple(half.tolist())
    points, normals = surface_samples(kind, model.geom_size[g], SURFACE_SPACING_M, mesh)
    rot = derive.quat_to_matrix(model.geom_quat[g])
    return CollisionShape(
        name=name, geom=g, link=links[int(model.geom_bodyid[g]) - 1], kind=kind, size=tuple(float(v) for v in model.geom_size[g]),
        pos=tuple(float(v) for v in model.geom_pos[g]), quat=tuple(float(v) for v in model.geom_quat[g]),
        points=points @ rot.T + model.geom_pos[g], normals=normals @ rot.T, box_centre=box_centre, box_half=box_half,
    )  # fmt: skip


def _buried(shapes: list[CollisionShape]):
    """A mask function: which of a link's samples (points, shape ids) lie more than ``BURIED_M`` inside another of its shapes."""

    def buried(points: np.ndarray, shape_ids: np.ndarray) -> np.ndarray:
        mask = np.zeros(len(points), dtype=bool)
        for s in set(shape_ids.tolist()):
            link = shapes[s].link
            for t, other in enumerate(shapes):
                if t == s or other.link != link:
                    continue
                rot = derive.quat_to_matrix(other.quat)
                local = (points - np.asarray(other.pos)) @ rot
                box = (np.asarray(other.box_centre), np.asarray(other.box_half)) if other.kind == "mesh" else None
                inside = signed_distance(other.kind, np.asarray(other.size), local, box) < -derive.BURIED_M
                mask |= inside & (shape_ids == s)
        return mask

    return buried


def _joints(model, links: tuple[str, ...]) -> tuple[Joint, ...]:
    import mujoco

    drive: dict[int, tuple[str, float | None]] = {}
    for a in range(model.nu):
        if model.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_JOINT:
            continue
        gain, bias = model.actuator_gainprm[a], model.actuator_biasprm[a]
        servo = model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE and bias[1] == -gain[0] and gain[0] > 0
        drive[int(model.actuator_trnid[a, 0])] = (model.actuator(a).name or f"actuator{a}", float(gain[0]) if servo else None)
    joints = []
    for j in range(model.njnt):
        name = model.joint(j).name or f"joint{j}"
        low, high = (float(v) for v in model.jnt_range[j])
        if not model.jnt_limited[j]:
            raise HandDescriptionError(f"joint {name} has no range: a hand's joints need limits")
        actuator, kp = drive.get(j, (None, None))
        joints.append(Joint(name, links[int(model.jnt_bodyid[j]) - 1], low, high, tuple(float(v) for v in model.jnt_axis[j]), actuator, kp))
    return tuple(joints)


def describe(model, name: str, source: str, *, xml_path: str | None = None, xml_string: str | None = None) -> HandDescription:
    """The description of a compiled hand model (see the module doc); raises ``HandDescriptionError``."""
    try:
        check_tree(model)
    except ChainError as exc:
        raise HandDescriptionError(str(exc)) from None
    links = body_names(model)
    parents = tuple(int(model.body_parentid[b]) - 1 for b in range(1, model.nbody))
    joints = _joints(model, links)
    used, left_out = collision_geoms(model)
    if not used:
        raise HandDescriptionError("no collision geoms (a geom with contype or conaffinity set)")
    shapes = [_shape(model, g, links) for g in used]

    index = {n: i for i, n in enumerate(links)}
    surfaces = {}
    for i in range(len(links)):
        ids = [s for s, shape in enumerate(shapes) if index[shape.link] == i]
        if ids:
            surfaces[i] = derive.LinkSurface(np.concatenate([shapes[s].points for s in ids]), np.concatenate([shapes[s].normals for s in ids]),
                                             np.concatenate([np.full(len(shapes[s].points), s) for s in ids]))  # fmt: skip
    jointed = tuple(bool(model.body_jntnum[b] > 0) for b in range(1, model.nbody))
    paths = derive.fingers(parents, jointed)
    if not paths:
        raise HandDescriptionError("no finger: no leaf body below the root moves with a joint")
    buried = _buried(shapes)
    finger_sides, contact_links = [], []
    points, normals, link_ids = [], [], []
    for path in paths:
        on_finger = tuple(i for i in derive.contact_links_of(path, jointed) if i in surfaces)
        sides = derive.pad_sides(model, path, on_finger, surfaces)
        finger_sides.append(sides)
        for link, side in sides.items():
            if link in contact_links:
                continue
            p, n = derive.facing(surfaces[link], side, buried, CONTACTS_PER_LINK)
            if len(p):
                contact_links.append(link)
                points.append(p), normals.append(n), link_ids.append(np.full(len(p), link))
    try:
        normal, voters = derive.palm_normal(model, finger_sides)
    except ValueError as exc:
        raise HandDescriptionError(str(exc)) from None
    palm_points = np.zeros((0, 3))
    if 0 in surfaces:
        palm_points, palm_normals = derive.facing(surfaces[0], normal, buried, PALM_CONTACTS)
        if len(palm_points):
            contact_links.append(0)
            points.append(palm_points), normals.append(palm_normals), link_ids.append(np.zeros(len(palm_points), dtype=int))
    origin = palm_points.mean(axis=0) if len(palm_points) else (surfaces[0].points.mean(axis=0) if 0 in surfaces else np.zeros(3))
    return HandDescription(
        name=name, source=source, links=links, parents=parents, joints=joints, shapes=tuple(shapes),
        left_out_geoms=tuple(model.geom(g).name or f"geom{g}" for g in left_out),
        fingers=tuple(tuple(links[i] for i in path) for path in paths), contact_links=tuple(links[i] for i in contact_links),
        contact_points=np.concatenate(points) if points else np.zeros((0, 3)),
        contact_normals=np.concatenate(normals) if normals else np.zeros((0, 3)),
        contact_link=np.concatenate(link_ids).astype(np.int64) if link_ids else np.zeros(0, dtype=np.int64),
        opposing=tuple(links[paths[f][-1]] for f in range(len(paths)) if f not in voters),
        palm_frame=derive.palm_frame(model, tuple(paths[f] for f in voters), normal, origin), pregrasp=derive.open_pregrasp(np.array([[j.lower, j.upper] for j in joints])),
        xml_path=xml_path, xml_string=xml_string,
    )  # fmt: skip


def hand_path(name_or_path: str | Path) -> Path | None:
    """The MJCF file a hand name or path stands for (None for the Shadow Hand, built in memory)."""
    text = str(name_or_path)
    if text == "shadow":
        return None
    if text in SHIPPED_HANDS:
        return HANDS_DIR / text / "right_hand.xml"
    return Path(text)


@functools.lru_cache(maxsize=8)
def _cached(key: str) -> HandDescription:
    path = hand_path(key)
    if path is None:
        from dexlite_pipeline.hand.mjcf import hand_mjcf_string

        text = hand_mjcf_string()
        return describe(_compile(None, text), "shadow", "gymnasium-robotics Shadow Hand, rooted at robot0:palm (hand.mjcf)", xml_string=text)
    if not path.is_file():
        raise HandDescriptionError(f"{path}: no such file (a hand is {', '.join(HAND_NAMES)} or an MJCF file)")
    try:
        text = path.read_text()
    except UnicodeDecodeError:
        raise HandDescriptionError(f"{path}: not XML (not a text file)") from None
    model = _compile(path, text)
    name = key if key in SHIPPED_HANDS else path.stem
    return describe(model, name, str(path), xml_path=str(path))


def hand_description(name_or_path: str | Path) -> HandDescription:
    """The description of ``shadow``, ``allegro``, ``leap`` or an MJCF file (cached per name or resolved path)."""
    text = str(name_or_path)
    return _cached(text if text in HAND_NAMES else str(Path(text).resolve()))


__all__ = ["HAND_NAMES", "CollisionShape", "HandDescription", "HandDescriptionError", "Joint", "collision_geoms", "describe",
           "hand_description", "hand_path"]
