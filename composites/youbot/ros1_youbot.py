"""The youBot arm in ROS 1's words (``youbot-ros1.composite``): the driver's status as a
``sensor_msgs/JointState``, the message ROS's robot_state_publisher, rviz and rqt_plot read.

``joint_state`` is the converter of the ``/joint_states`` stream: names as the youBot's
own ROS driver calls its arm joints, each joint's position [rad], velocity [rad/s] and,
for effort, its motor current [A] (the dummy arm has no torque sensor); the header is
stamped with the sample's own time and sequence number, not the time it was sent.
"""

from __future__ import annotations

from youbot_model import YouBotStatus

__all__ = ["JOINT_NAMES", "joint_state"]

#: The arm joints as youbot_driver_ros_interface names them.
JOINT_NAMES = ("arm_joint_1", "arm_joint_2", "arm_joint_3", "arm_joint_4", "arm_joint_5")


def joint_state(status: YouBotStatus) -> dict:
    """``status`` as the fields of a ``sensor_msgs/JointState``."""
    sec, nanosec = divmod(round(status.timestamp * 1e9), 1_000_000_000)
    joints = status.joints[: len(JOINT_NAMES)]
    return {
        "header": {"seq": status.sequence & 0xFFFFFFFF, "stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": ""},
        "name": list(JOINT_NAMES[: len(joints)]),
        "position": [j.position for j in joints],
        "velocity": [j.velocity for j in joints],
        "effort": [j.current for j in joints],
    }
