"""The youBot arm's frames: its joint angles become ``base_link → arm_link_0 … arm_link_5``.

The numbers are the youBot's own, as its ROS description publishes them (the
``youbot_description`` package, github.com/mas-group/youbot_description):

* ``robots/youbot.urdf.xacro``: the arm mounted on ``base_link`` at ``xyz="0.143 0 0.046"``;
* ``urdf/youbot_arm/arm.urdf.xacro``: ``arm_joint_1`` … ``arm_joint_5``, each a revolute
  joint with an ``origin`` (xyz in m, rpy in rad) from its parent link and an ``axis``.

The dummy driver's positions are relative to the candle pose (the arm straight up, see
:data:`youbot_model.JOINT_LIMITS`); in the URDF the candle is where each joint's angle undoes
its origin's rotation (:data:`CANDLE`), so a URDF angle is ``CANDLE[j] + position[j]``.
Each joint's transform is its origin, then a rotation of that angle about its axis.

:class:`Gripper` is a task that reads the tree as any task does (``self.frames``) and puts
the gripper's position in ``base_link`` on a port, for the monitor.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from pydantic import BaseModel

from dataflow import OutputPort, TaskContext, register_type
from dataflow.tf import Transform, TransformError

__all__ = ["BASE_FRAME", "CANDLE", "GRIPPER_FRAME", "JOINTS", "MOUNT", "Gripper", "GripperPosition", "arm_frames",
           "mount"]

BASE_FRAME = "base_link"
GRIPPER_FRAME = "arm_link_5"  #: the gripper's palm is mounted on it with no offset (youbot.urdf.xacro)
#: base_link → arm_link_0, fixed: xyz [m], rpy [rad]
MOUNT = ((0.143, 0.0, 0.046), (0.0, 0.0, 0.0))
_DEG = math.pi / 180.0
#: (parent, child, origin xyz [m], origin rpy [rad], axis) of arm_joint_1 … arm_joint_5
JOINTS: tuple[tuple[str, str, tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]], ...] = (
    ("arm_link_0", "arm_link_1", (0.024, 0.0, 0.096), (0.0, 0.0, 170 * _DEG), (0.0, 0.0, -1.0)),
    ("arm_link_1", "arm_link_2", (0.033, 0.0, 0.019), (0.0, -65 * _DEG, 0.0), (0.0, 1.0, 0.0)),
    ("arm_link_2", "arm_link_3", (0.0, 0.0, 0.155), (0.0, 146 * _DEG, 0.0), (0.0, 1.0, 0.0)),
    ("arm_link_3", "arm_link_4", (0.0, 0.0, 0.135), (0.0, -102.5 * _DEG, 0.0), (0.0, 1.0, 0.0)),
    ("arm_link_4", "arm_link_5", (-0.002, 0.0, 0.130), (0.0, 0.0, 167.5 * _DEG), (0.0, 0.0, -1.0)),
)
#: The URDF joint angles [rad] of the candle pose, the dummy driver's zero.
CANDLE = (170 * _DEG, 65 * _DEG, -146 * _DEG, 102.5 * _DEG, 167.5 * _DEG)


def mount() -> Transform:
    """base_link → arm_link_0: static."""
    return Transform.from_rpy(BASE_FRAME, "arm_link_0", *MOUNT)


def arm_frames(positions: Sequence[float], stamp_ns: int) -> list[Transform]:
    """The five joints' transforms at ``stamp_ns`` for the driver's ``positions`` [rad]."""
    out = []
    for (parent, child, xyz, rpy, axis), candle, position in zip(JOINTS, CANDLE, positions, strict=True):
        origin = Transform.from_rpy(parent, child, xyz, rpy, stamp_ns)
        half = (candle + position) / 2.0
        s = math.sin(half)
        turn = Transform(child, child, rotation=(axis[0] * s, axis[1] * s, axis[2] * s, math.cos(half)))
        joint = origin * turn
        out.append(Transform(parent, child, joint.translation, joint.rotation, stamp_ns))
    return out


@register_type("YouBotGripperPosition")
class GripperPosition(BaseModel):
    """Where the gripper (``arm_link_5``) is in ``base_link`` [m], at ``stamp`` [s]."""

    x: float
    y: float
    z: float
    stamp: float


class Gripper(TaskContext):
    """Looks the gripper up in ``base_link`` each period, in its process's frame tree."""

    position = OutputPort(GripperPosition, doc="the gripper (arm_link_5) in base_link [m]")

    def update_hook(self) -> None:
        try:
            seen = self.frames.lookup(BASE_FRAME, GRIPPER_FRAME)
        except TransformError:  # the driver has not published yet
            return
        x, y, z = seen.translation
        self.position.write(GripperPosition(x=x, y=y, z=z, stamp=seen.stamp))
