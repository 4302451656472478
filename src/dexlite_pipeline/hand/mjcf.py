"""The Shadow Hand MJCF, rooted at ``robot0:palm``, built from the installed gymnasium-robotics model.

The model files are read from the installed package at run time (MIT licence), never
copied into this repository. The forearm, wrist, WRJ1 and WRJ0 are dropped and the
palm is placed at the origin of its parent: the result is DexGraspNet's hand.
"""

from __future__ import annotations

import copy
import functools
import xml.etree.ElementTree as ET
from pathlib import Path

PALM_BODY = "robot0:palm"
WRIST_JOINTS = ("robot0:WRJ1", "robot0:WRJ0")


@functools.cache
def gym_hand_asset_dir() -> Path:
    """Folder of the gymnasium-robotics hand assets (``hand/`` and ``stls/hand/`` below it)."""
    import importlib.util

    spec = importlib.util.find_spec("gymnasium_robotics")
    if spec is None or spec.origin is None:
        raise RuntimeError("gymnasium-robotics is not installed: it ships the Shadow Hand model (pip install gymnasium-robotics)")
    assets = Path(spec.origin).parent / "envs" / "assets"
    if not (assets / "hand" / "robot.xml").is_file():
        raise RuntimeError(f"{assets / 'hand' / 'robot.xml'}: Shadow Hand model not found in the installed gymnasium-robotics")
    return assets


def _palm_body() -> ET.Element:
    robot = ET.parse(gym_hand_asset_dir() / "hand" / "robot.xml").getroot()
    palm = next(b for b in robot.iter("body") if b.get("name") == PALM_BODY)
    palm = copy.deepcopy(palm)
    palm.set("pos", "0 0 0")
    for joint in list(palm.findall("joint")):
        if joint.get("name") in WRIST_JOINTS:
            palm.remove(joint)
    # The classes of the subtree were inherited from the forearm body: keep them.
    palm.set("childclass", "robot0:asset_class")
    return palm


def _shared_sections() -> tuple[ET.Element, list[ET.Element]]:
    """The <default> block and the hand's <contact> pairs from shared.xml."""
    shared = ET.parse(gym_hand_asset_dir() / "hand" / "shared.xml").getroot()
    default = copy.deepcopy(shared.find("default"))
    contact = shared.find("contact")
    pairs = [copy.deepcopy(p) for p in contact] if contact is not None else []
    return default, pairs


def _mesh_assets() -> list[ET.Element]:
    shared_asset = ET.parse(gym_hand_asset_dir() / "hand" / "shared_asset.xml").getroot()
    stl_dir = gym_hand_asset_dir() / "stls" / "hand"
    meshes = []
    for mesh in shared_asset.findall("mesh"):
        if "forearm" in mesh.get("name", ""):
            continue
        mesh = copy.deepcopy(mesh)
        mesh.set("file", str(stl_dir / mesh.get("file")))
        meshes.append(mesh)
    materials = [copy.deepcopy(m) for m in shared_asset.findall("material") if m.get("name") in ("robot0:MatColl", "robot0:MatViz")]
    return meshes + materials


def hand_mjcf(*, free_root: bool = False, model_name: str = "shadow_hand") -> ET.Element:
    """A complete <mujoco> element holding only the palm-rooted hand.

    free_root: give the palm a free joint (for a mocap weld in the lift test); otherwise
    the palm is fixed at the world origin (for kinematics checks). Tendons, sensors and
    actuators of the gym model are left out: callers add the actuators they need.
    """
    root = ET.Element("mujoco", model=model_name)
    ET.SubElement(root, "compiler", angle="radian", coordinate="local")
    default, pairs = _shared_sections()
    root.append(default)
    asset = ET.SubElement(root, "asset")
    for element in _mesh_assets():
        asset.append(element)
    worldbody = ET.SubElement(root, "worldbody")
    palm = _palm_body()
    if free_root:
        palm.insert(0, ET.Element("freejoint", name="robot0:palm_free"))
    worldbody.append(palm)
    if pairs:
        contact = ET.SubElement(root, "contact")
        for pair in pairs:
            contact.append(pair)
    return root


def hand_mjcf_string(**kwargs) -> str:
    """``hand_mjcf`` serialized to an XML string (``mujoco.MjModel.from_xml_string`` input)."""
    return ET.tostring(hand_mjcf(**kwargs), encoding="unicode")
