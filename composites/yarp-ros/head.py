"""The ROS–YARP bridge of seeds 000 and 001, as a composite (``yarp-ros.composite``): an iCub
head speaks YARP, a ROS graph speaks ROS, and two type-checked ``<scart:bridge>`` s join
them with nothing else in between.

* YARP → ROS: the head's encoders, a bottle of 6 angles in **degrees** on the YARP port
  ``/icub/head/state:o`` (as iCub's ``controlboardwrapper`` writes them), become a
  ``sensor_msgs/JointState`` in **radians**, with the head's joint names, on ``/joint_states``.
* ROS → YARP: a ``std_msgs/Float64MultiArray`` of target angles in radians on
  ``/head/target`` becomes a bottle of degrees for the YARP port ``/icub/head/target:i``.

Each builder's annotations are the bridge's contract: checked at load against the types of
the topics on either side (``scart validate``), so a builder taking the wrong type is
refused at its line before anything runs — what seed 000's generated bridge could not do.
"""

from __future__ import annotations

import math

from pydantic import BaseModel, Field

__all__ = ["HEAD_JOINTS", "JointState", "joint_state", "to_degrees"]

#: The iCub head's joints, in the order its control board writes them.
HEAD_JOINTS = ("neck_pitch", "neck_roll", "neck_yaw", "eyes_tilt", "eyes_version", "eyes_vergence")


class JointState(BaseModel):
    """The fields of a ``sensor_msgs/JointState`` the bridge fills (its header is stamped
    with the sample's time on the way out)."""

    name: list[str] = Field(default_factory=list)
    position: list[float] = Field(default_factory=list)
    velocity: list[float] = Field(default_factory=list)
    effort: list[float] = Field(default_factory=list)


def joint_state(encoders: list[float]) -> JointState:
    """The head's encoders (degrees, YARP's unit) as a JointState (radians, ROS's unit)."""
    return JointState(name=list(HEAD_JOINTS[: len(encoders)]), position=[math.radians(a) for a in encoders])


def to_degrees(target: list[float]) -> list[float]:
    """Target angles from ROS (radians) for the head's YARP port (degrees)."""
    return [math.degrees(a) for a in target]
