"""Writes `openclaw.urdf`, the project's own claw arm, from a few plain dimensions.

The URDF is committed; this script is how it was made, and a test checks the
committed file still equals its output. Run: `python -m robots.descriptions.openclaw_build`.

All collision geometry is primitive (boxes and cylinders) so that PhysX and
FCL stay fast; the visual geometry repeats it with colours for the browser.
Units: metres, kilograms, radians, newtons.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

URDF_PATH = Path(__file__).with_name("openclaw.urdf")


@dataclass(frozen=True)
class Body:
    """One link's single primitive: a box (size xyz) or a cylinder (radius, length) along z."""

    name: str
    mass_kg: float
    center_xyz: tuple[float, float, float]
    box_xyz: tuple[float, float, float] | None = None
    cylinder_rl: tuple[float, float] | None = None
    colour: str = "0.85 0.55 0.10 1"

    def inertia(self) -> tuple[float, float, float]:
        """Principal moments (ixx, iyy, izz) of a solid box or cylinder about its centre."""
        m = self.mass_kg
        if self.box_xyz is not None:
            x, y, z = self.box_xyz
            return (m * (y * y + z * z) / 12, m * (x * x + z * z) / 12, m * (x * x + y * y) / 12)
        r, h = self.cylinder_rl  # type: ignore[misc]
        side = m * (3 * r * r + h * h) / 12
        return (side, side, m * r * r / 2)

    def geometry_xml(self) -> str:
        if self.box_xyz is not None:
            return '<box size="{:g} {:g} {:g}"/>'.format(*self.box_xyz)
        r, h = self.cylinder_rl  # type: ignore[misc]
        return f'<cylinder radius="{r:g}" length="{h:g}"/>'


@dataclass(frozen=True)
class Joint:
    name: str
    kind: str  # revolute | prismatic | fixed
    parent: str
    child: str
    origin_xyz: tuple[float, float, float]
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    lower: float = 0.0
    upper: float = 0.0
    velocity: float = 0.0
    effort: float = 0.0


ORANGE = "0.90 0.50 0.10 1"
GREY = "0.25 0.25 0.28 1"
PAD = "0.10 0.10 0.10 1"

BODIES = [
    Body("base_link", 3.0, (0, 0, 0.04), cylinder_rl=(0.07, 0.08), colour=GREY),
    Body("shoulder_link", 1.2, (0, 0, 0.035), cylinder_rl=(0.055, 0.07), colour=ORANGE),
    Body("upper_arm_link", 1.0, (0, 0, 0.14), box_xyz=(0.06, 0.06, 0.28), colour=ORANGE),
    Body("forearm_link", 0.6, (0, 0, 0.06), box_xyz=(0.05, 0.05, 0.12), colour=GREY),
    Body("forearm_roll_link", 0.4, (0, 0, 0.06), box_xyz=(0.045, 0.045, 0.12), colour=ORANGE),
    Body("wrist_link", 0.25, (0, 0, 0.03), box_xyz=(0.04, 0.04, 0.06), colour=GREY),
    Body("palm_link", 0.3, (0, 0, 0.015), box_xyz=(0.04, 0.10, 0.03), colour=GREY),
    Body("finger_left_link", 0.04, (0, 0.006, 0.03), box_xyz=(0.02, 0.012, 0.06), colour=PAD),
    Body("finger_right_link", 0.04, (0, -0.006, 0.03), box_xyz=(0.02, 0.012, 0.06), colour=PAD),
]

JOINTS = [
    Joint("shoulder_pan", "revolute", "base_link", "shoulder_link", (0, 0, 0.08), (0, 0, 1), -2.9, 2.9, 2.5, 60),
    Joint("shoulder_lift", "revolute", "shoulder_link", "upper_arm_link", (0, 0, 0.07), (0, 1, 0), -1.9, 1.9, 2.5, 60),
    Joint("elbow", "revolute", "upper_arm_link", "forearm_link", (0, 0, 0.28), (0, 1, 0), -2.6, 2.6, 3.0, 40),
    Joint("forearm_roll", "revolute", "forearm_link", "forearm_roll_link", (0, 0, 0.12), (0, 0, 1), -2.9, 2.9, 4.0, 12),
    Joint("wrist_pitch", "revolute", "forearm_roll_link", "wrist_link", (0, 0, 0.12), (0, 1, 0), -2.1, 2.1, 4.0, 12),
    Joint("wrist_roll", "revolute", "wrist_link", "palm_link", (0, 0, 0.06), (0, 0, 1), -2.9, 2.9, 4.0, 12),
    Joint("finger_left", "prismatic", "palm_link", "finger_left_link", (0, 0, 0.03), (0, 1, 0), 0.002, 0.035, 0.15, 40),
    Joint(
        "finger_right", "prismatic", "palm_link", "finger_right_link", (0, 0, 0.03), (0, -1, 0), 0.002, 0.035, 0.15, 40
    ),
    # The tool frame sits between the fingertip pads, z pointing out of the palm (the approach axis).
    Joint("tool_joint", "fixed", "palm_link", "tool_link", (0, 0, 0.06)),
]


def _fmt(values: tuple[float, ...]) -> str:
    return " ".join(f"{v:g}" for v in values)


def _link_xml(body: Body) -> str:
    ixx, iyy, izz = body.inertia()
    origin = f'<origin xyz="{_fmt(body.center_xyz)}" rpy="0 0 0"/>'
    geometry = body.geometry_xml()
    return f"""  <link name="{body.name}">
    <inertial>
      {origin}
      <mass value="{body.mass_kg:g}"/>
      <inertia ixx="{ixx:.6g}" ixy="0" ixz="0" iyy="{iyy:.6g}" iyz="0" izz="{izz:.6g}"/>
    </inertial>
    <visual>
      {origin}
      <geometry>{geometry}</geometry>
      <material name="{body.name}_colour"><color rgba="{body.colour}"/></material>
    </visual>
    <collision>
      {origin}
      <geometry>{geometry}</geometry>
    </collision>
  </link>
"""


def _joint_xml(joint: Joint) -> str:
    head = f'  <joint name="{joint.name}" type="{joint.kind}">\n'
    body = (
        f'    <parent link="{joint.parent}"/>\n    <child link="{joint.child}"/>\n'
        f'    <origin xyz="{_fmt(joint.origin_xyz)}" rpy="0 0 0"/>\n'
    )
    if joint.kind != "fixed":
        body += f'    <axis xyz="{_fmt(joint.axis)}"/>\n'
        body += (
            f'    <limit lower="{joint.lower:g}" upper="{joint.upper:g}" '
            f'velocity="{joint.velocity:g}" effort="{joint.effort:g}"/>\n'
        )
    return head + body + "  </joint>\n"


def build_urdf() -> str:
    """The OpenClaw URDF as text."""
    parts = [
        '<?xml version="1.0"?>\n',
        "<!-- Generated by robots/descriptions/openclaw_build.py: edit that, not this. -->\n",
    ]
    parts.append('<robot name="openclaw">\n')
    parts.extend(_link_xml(b) for b in BODIES)
    parts.append('  <link name="tool_link"/>\n')
    parts.extend(_joint_xml(j) for j in JOINTS)
    parts.append("</robot>\n")
    return "".join(parts)


if __name__ == "__main__":
    URDF_PATH.write_text(build_urdf())
    print(f"wrote {URDF_PATH}")
