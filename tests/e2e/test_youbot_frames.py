"""The youBot publishes its arm: joint angles → ``base_link → arm_link_0 … arm_link_5``.

The frames are checked against forward kinematics written here independently (4x4
matrices from the URDF's origins and axes, with numpy), in a deployer's tree; then the
ROS 1 demo (``youbot-ros1.composite``) puts them on ``/tf``, where tf2_ros'
``TransformListener`` sees the arm move when ``rostopic pub /youbot/pose`` moves it; and
the monitor of ``youbot.composite`` shows where the gripper is in ``base_link``."""

from __future__ import annotations

import math
import random
from pathlib import Path

import numpy as np
import pytest
from support import wait_until
from support.ros1 import needs_ros, rosmaster
from support.tf2 import Peer, require_tf2
from support.youbot import Demo, monitor_state, ns_address, post_json, start_serving

from dataflow import Deployer, OutputPort, SlaveActivity
from driver import YouBotDriver
from youbot_arm import CANDLE, JOINTS, MOUNT, arm_frames, mount

TOLERANCE = 1e-9


def _rotation(rpy: tuple[float, float, float]) -> np.ndarray:
    r, p, y = rpy
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def _about(axis: tuple[float, float, float], angle: float) -> np.ndarray:
    k = np.array(axis, dtype=float)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * cross + (1 - math.cos(angle)) * cross @ cross  # Rodrigues


def _homogeneous(rotation: np.ndarray, xyz: tuple[float, float, float]) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rotation, xyz
    return out


def gripper_by_hand(positions: list[float]) -> np.ndarray:
    """arm_link_5's origin in base_link: the URDF's chain as 4x4 matrices."""
    pose = _homogeneous(_rotation(MOUNT[1]), MOUNT[0])
    for (_, _, xyz, rpy, axis), candle, q in zip(JOINTS, CANDLE, positions, strict=True):
        pose = pose @ _homogeneous(_rotation(rpy), xyz) @ _homogeneous(_about(axis, candle + q), (0.0, 0.0, 0.0))
    return pose[:3, 3]


def test_the_arm_frames_are_the_urdfs_chain() -> None:
    deployer = Deployer()
    frames = deployer.frames
    frames.publish(mount(), static=True)
    rng = random.Random(7)
    for k in range(20):
        positions = [rng.uniform(-1.5, 1.5) for _ in range(5)]
        frames.publish(arm_frames(positions, (k + 1) * 10**9))
        seen = frames.lookup("base_link", "arm_link_5", float(k + 1)).translation
        assert np.allclose(seen, gripper_by_hand(positions), atol=TOLERANCE, rtol=0), positions
    assert np.allclose(gripper_by_hand([0.0] * 5), (0.198, 0.0, 0.581), atol=1e-12)  # the candle: straight up


def test_the_driver_publishes_its_joint_angles_as_frames() -> None:
    deployer = Deployer()
    driver = deployer.add(YouBotDriver("youBotDriver"))
    driver.set_activity(SlaveActivity())
    assert driver.configure() and driver.start()
    out: OutputPort[list[float]] = OutputPort(list[float])
    out.connect_to(driver.commands)
    out.write([0.5, 0.2, -0.3, 0.1, 0.0])
    for _ in range(30):
        driver.update()
    sample = driver.status.last_sample()[1]
    seen = deployer.frames.lookup("base_link", "arm_link_5")  # the newest: the last cycle's
    assert abs(seen.stamp - sample.timestamp) < 1e-6  # stamped with the sample's own time
    assert np.allclose(seen.translation, gripper_by_hand(driver.positions), atol=TOLERANCE, rtol=0)
    assert seen.frame_id == "base_link" and deployer.frames.frames()[0].authority == "youBotDriver"
    driver.stop()


@pytest.mark.integration
@pytest.mark.subprocess
@needs_ros
def test_tf2_ros_sees_the_arm_move_when_ros_moves_it(tmp_path: Path) -> None:
    require_tf2()
    with rosmaster(tmp_path) as ros:
        demo = Demo("youbot-ros1.composite", ns_address(), "--ros-master", ros.uri)
        peer = Peer(ros, "listen")
        try:
            demo.wait_line("scart: started", 60)
            assert "ready" in peer.next(60)
            candle = wait_until(lambda: (a := peer.ask(lookup=["base_link", "arm_link_5", 0])).get("t") and a,
                                timeout=30, interval=0.1, message="tf2 never saw the arm")
            assert np.allclose(candle["t"], gripper_by_hand([0.0] * 5), atol=1e-6)  # (noise-free: the candle)
            target = [0.5, 0.2, -0.3, 0.1, 0.0]
            done = ros.tool("rostopic", "pub", "-1", "/youbot/pose", "std_msgs/Float64MultiArray",
                            f"{{data: {target}}}", timeout=60)
            assert done.returncode == 0, done.stderr
            expected = gripper_by_hand(target)

            def there() -> bool:
                seen = peer.ask(lookup=["base_link", "arm_link_5", 0])
                return "t" in seen and bool(np.allclose(seen["t"], expected, atol=TOLERANCE, rtol=0))

            wait_until(there, timeout=30, interval=0.1, message="tf2 never saw the arm reach the pose")
            static = peer.ask(lookup=["base_link", "arm_link_0", 0])
            assert static["t"] == [0.143, 0.0, 0.046]
        finally:
            peer.stop()
            assert demo.stop() == 0, demo.output()


@pytest.mark.integration
@pytest.mark.subprocess
def test_the_monitor_shows_the_gripper_in_base_link() -> None:
    demo = start_serving("youbot.composite")
    try:
        url = demo.monitor_url()
        shown = wait_until(lambda: monitor_state(url).get("gripper"), 20, 0.05, "no gripper shown")
        assert np.allclose([shown["x"], shown["y"], shown["z"]], gripper_by_hand([0.0] * 5), atol=1e-6)
        assert post_json(url + "api/pose", {"pose": [0.0, 1.0, 0.0, 0.0, 0.0]})["ok"]
        moved = gripper_by_hand([0.0, 1.0, 0.0, 0.0, 0.0])
        wait_until(lambda: np.allclose([(g := monitor_state(url)["gripper"])["x"], g["y"], g["z"]], moved, atol=1e-6),
                   30, 0.05, "the monitor never showed the gripper move")
    finally:
        assert demo.stop() == 0, demo.output()

