"""``scart tf echo`` and ``scart tf frames`` (real subprocesses) against a served frame tree:
a deployer in this process serving a :class:`~dataflow.tf.FrameServer`, with a static
chain and a frame that moves while the commands run."""

from __future__ import annotations

import json
import math
import threading
import time
from collections.abc import Iterator

import pytest
from support.cli import run

from dataflow import Deployer
from dataflow.tf import FrameServer, Transform
from dataflow.tf._math import axis_angle

pytestmark = [pytest.mark.integration, pytest.mark.subprocess]


@pytest.fixture(scope="module")
def ns() -> Iterator[str]:
    """A served tree: world → base (static: 1, 2, 3 m, turned 90° about z) → wheel (moving at 50 Hz)."""
    deployer = Deployer()
    server = deployer.add(FrameServer("tf", deployer.frames))
    deployer.frames.publish(Transform("world", "base", (1.0, 2.0, 3.0), axis_angle((0.0, 0.0, 1.0), math.pi / 2)),
                            static=True, authority="test")
    stop = threading.Event()

    def turn() -> None:
        for k in range(100_000):
            deployer.frames.publish(Transform("base", "wheel", (0.5, 0.0, 0.0), axis_angle((0.0, 1.0, 0.0), 0.01 * k),
                                              time.time_ns()), authority="spinner")
            if stop.wait(0.02):
                return

    spinner = threading.Thread(target=turn, name="test-tf-spinner")
    assert server.configure() and server.start()
    spinner.start()
    served = deployer.serve("127.0.0.1:0")
    try:
        yield served.ns_address
    finally:
        stop.set()
        spinner.join(5)
        served.stop()
        server.stop()


def test_echo_prints_the_pose_as_tf_echo_does(ns: str) -> None:
    done = run("tf", "echo", "world", "base", "--once", "--ns", ns)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[1:] == ["- Translation: [1.000, 2.000, 3.000]",
                                            "- Rotation: in Quaternion [0.000, 0.000, 0.707, 0.707]",
                                            "            in RPY (radian) [0.000, 0.000, 1.571]",
                                            "            in RPY (degree) [0.000, 0.000, 90.000]"], done.stdout
    assert done.stdout.startswith("At time 0.000")


def test_echo_follows_a_moving_frame(ns: str) -> None:
    done = run("tf", "echo", "world", "wheel", "-n", "2", "--rate", "20", "--json", "--ns", ns)
    assert done.returncode == 0, done.stderr
    first, second = (json.loads(line) for line in done.stdout.splitlines())
    assert first["frame_id"] == "world" and first["child_frame_id"] == "wheel"
    assert first["translation"] == pytest.approx([1.0, 2.5, 3.0]) and second["time"] > first["time"] > 0


def test_echo_of_a_frame_that_never_comes_fails_saying_why(ns: str) -> None:
    done = run("tf", "echo", "world", "nowhere", "--once", "--duration", "0.5", "--ns", ns)
    assert done.returncode == 1 and done.stdout == ""
    assert "tf echo: no transform from world to nowhere: " in done.stderr and "no frame 'nowhere'" in done.stderr
    nothing = run("tf", "frames", "--server", "nope", "--ns", ns)
    assert nothing.returncode == 1 and "a composite serves its frame tree with <scart:frames/>" in nothing.stderr


def test_frames_prints_the_tree_with_parents_rates_and_ages(ns: str) -> None:
    done = run("tf", "frames", "--ns", ns)
    assert done.returncode == 0, done.stderr
    rows = [line.split() for line in done.stdout.splitlines()]
    assert rows[0] == ["FRAME", "PARENT", "RATE", "AGE", "KEPT", "BY"]
    assert rows[1] == ["world", "-"]
    assert rows[2][:3] == ["base", "world", "static"] and rows[2][-1] == "test"
    assert done.stdout.splitlines()[3].startswith("    wheel  ")  # under base
    wheel = rows[3]
    assert wheel[1] == "base" and wheel[-1] == "spinner" and 30 < float(wheel[2]) < 70 and wheel[3] == "Hz"
    assert rows[-1][:2] == ["2", "frame(s),"]
    dot = run("tf", "frames", "--dot", "--ns", ns)
    assert dot.returncode == 0 and '"world" -> "base"' in dot.stdout and '"base" -> "wheel"' in dot.stdout
    assert "Broadcaster: spinner" in dot.stdout and dot.stdout.startswith("digraph frames {")
    tree = json.loads(run("tf", "frames", "--json", "--ns", ns).stdout)
    assert tree["roots"] == ["world"] and {f["frame"] for f in tree["frames"]} == {"base", "wheel"}
