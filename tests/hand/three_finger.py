"""A small three-finger hand built from MJCF primitives, written by the tests (and shown in docs/hands.md).

A flat box palm in the x-y plane facing -z, two fingers along +x and a thumb along -y, each of
capsules on hinges that curl toward -z (flexion toward the upper limit). The root body sits at
a translated, rotated pose in the world, so a chain that dropped the root's offset would fail
the FK comparison with MuJoCo. The joints' damping (0.1 N·m·s/rad) and armature (0.001 kg·m²) are the Shadow
Hand's: without them MuJoCo's position servos on such light links are unstable at the lift test's 2 ms step.
Lengths in metres, angles in radians.
"""

from __future__ import annotations

from pathlib import Path


def _finger(name: str, pos: str, axis: str, along: str, lengths: tuple[float, ...]) -> str:
    """Nested bodies, one capsule and one hinge each, the first at ``pos`` in the palm."""
    direction = [float(v) for v in along.split()]
    xml, close = "", ""
    for k, length in enumerate(lengths):
        here = pos if k == 0 else " ".join(f"{v * lengths[k - 1]:g}" for v in direction)
        tip = " ".join(f"{v * length:g}" for v in direction)
        joint_range = "-0.3 0.3" if k == 0 and name == "th" else "-0.2 1.57"
        joint_axis = "0 0 1" if k == 0 and name == "th" else axis
        xml += (f'<body name="{name}{k}" pos="{here}"><joint name="{name}_j{k}" axis="{joint_axis}" range="{joint_range}"/>'
                f'<geom name="{name}{k}_capsule" type="capsule" fromto="0 0 0 {tip}" size="0.008"/>')
        close += "</body>"
    return xml + close


THREE_FINGER_XML = f"""<mujoco model="three_finger">
  <compiler angle="radian" autolimits="true"/>
  <default>
    <joint damping="0.1" armature="0.001"/>
  </default>
  <worldbody>
    <body name="palm" pos="0.1 -0.05 0.2" quat="0.9 0.1 0.3 0.2">
      <geom name="palm_box" type="box" size="0.04 0.035 0.01"/>
      {_finger("f1", "0.045 0.02 0", "0 1 0", "1 0 0", (0.04, 0.03, 0.025))}
      {_finger("f2", "0.045 -0.02 0", "0 1 0", "1 0 0", (0.04, 0.03, 0.025))}
      {_finger("th", "0 -0.04 0", "1 0 0", "0 -1 0", (0.012, 0.035, 0.03))}
    </body>
  </worldbody>
  <actuator>
    <position name="f1_a1" joint="f1_j1" kp="2"/>
  </actuator>
</mujoco>
"""


def write_three_finger(folder: Path) -> Path:
    """Write the hand to ``folder/three_finger.xml`` and return the path."""
    path = folder / "three_finger.xml"
    path.write_text(THREE_FINGER_XML)
    return path
