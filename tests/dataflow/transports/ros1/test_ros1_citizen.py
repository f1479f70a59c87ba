"""scart's ROS 1 node as a citizen of a ROS system, judged by ROS's own tools against a
``scart deploy`` subprocess: ``rosnode kill`` ends it as rospy ends, saying who asked."""

from __future__ import annotations

import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from support import free_port, wait_until
from support.remote import start_scart, stop_process, subprocess_env
from support.ros1 import RosMaster, needs_ros

pytestmark = [pytest.mark.integration, pytest.mark.subprocess, needs_ros]


def scart(*args: str, ns: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "scart", *args, "--ns", ns], capture_output=True, text=True,
                          timeout=60, env=subprocess_env())


def deploy(ros: RosMaster, name: str, *extra: str) -> tuple[subprocess.Popen[str], str]:
    """``scart deploy`` of a Gauge as the ROS node ``/NAME``; (process, its name service)."""
    ns = f"127.0.0.1:{free_port()}"
    proc, _ = start_scart(["deploy", "support.ros1_tasks:Gauge", "--period", "0.05", "--ns", ns,
                           "--ros-master", ros.uri, "--ros-name", name, *extra])
    return proc, ns


def nodes(ros: RosMaster) -> list[str]:
    return ros.tool("rosnode", "list").stdout.split()


def test_rosnode_kill_ends_scart_deploy_saying_who_asked(ros: RosMaster) -> None:
    proc, ns = deploy(ros, "doomed")
    try:
        made = scart("stream", "gauge.count", "ros1:/doomed/count", ns=ns)
        assert made.returncode == 0, made.stderr
        wait_until(lambda: "/doomed" in nodes(ros), timeout=20)
        killed = ros.tool("rosnode", "kill", "/doomed")
        assert killed.returncode == 0, killed.stderr
        assert proc.wait(timeout=30) == 0
        said = proc.stderr.read() if proc.stderr else ""
        assert "the ROS node /doomed was shut down by /rosnode (user request): stopping" in said, said
        assert "/doomed" not in nodes(ros)  # everything it had registered is gone with it
    finally:
        stop_process(proc)


def stop(proc: subprocess.Popen[str]) -> str:
    """Stop ``proc`` as Ctrl-C does; what it said on stderr."""
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    return err


def rosparam(ros: RosMaster, *args: str) -> str:
    done = ros.tool("rosparam", *args)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def test_task_properties_are_the_nodes_parameters(ros: RosMaster) -> None:
    key = "/params/gauge/ceiling"
    rosparam(ros, "set", key, "7.0")  # what an earlier run left: the task's value wins
    proc, ns = deploy(ros, "params", "_gauge/ceiling:=0.5")
    try:
        wait_until(lambda: rosparam(ros, "get", key) == "0.5", timeout=20)  # the launch-time value, checked
        assert rosparam(ros, "get", "/params/gauge/note") == "''"
        rosparam(ros, "set", key, "2.5")
        wait_until(lambda: scart("prop", "get", "gauge", "ceiling", ns=ns).stdout.strip() == "2.5", timeout=10)
        rosparam(ros, "set", key, "99")  # beyond the property's bounds: refused, and set back
        wait_until(lambda: rosparam(ros, "get", key) == "2.5", timeout=10)
        assert scart("prop", "get", "gauge", "ceiling", ns=ns).stdout.strip() == "2.5"
        assert scart("prop", "set", "gauge", "ceiling", "3.5", ns=ns).returncode == 0
        wait_until(lambda: rosparam(ros, "get", key) == "3.5", timeout=10)  # a change made elsewhere
    finally:
        said = stop(proc)
    assert f"ROS parameter {key}: 99 refused: gauge.ceiling" in said and "it keeps 2.5" in said, said


def test_a_refused_launch_time_parameter_fails_the_launch(ros: RosMaster) -> None:
    done = subprocess.run([sys.executable, "-m", "scart", "deploy", "support.ros1_tasks:Gauge", "_gauge/ceiling:=50",
                           "--ns", f"127.0.0.1:{free_port()}", "--ros-master", ros.uri], capture_output=True,
                          text=True, timeout=60, env=subprocess_env())
    assert done.returncode == 1
    assert "ROS parameter _gauge/ceiling:=50: refused: gauge.ceiling" in done.stderr, done.stderr


def test_a_plain_private_parameter_at_launch_sets_the_one_task_that_has_it(ros: RosMaster) -> None:
    proc, ns = deploy(ros, "plain", "_ceiling:=0.5")
    try:
        wait_until(lambda: rosparam(ros, "get", "/plain/gauge/ceiling") == "0.5", timeout=20)
    finally:
        stop(proc)
    two = subprocess.run([sys.executable, "-m", "scart", "deploy", "support.ros1_tasks:Gauge@left",
                          "support.ros1_tasks:Gauge@right", "_ceiling:=0.5", "--ns", f"127.0.0.1:{free_port()}",
                          "--ros-master", ros.uri], capture_output=True, text=True, timeout=60, env=subprocess_env())
    assert two.returncode == 1
    assert "ROS parameter _ceiling: the tasks left, right have that property: name one" in two.stderr, two.stderr


def test_a_plain_private_parameter_no_task_has_is_refused() -> None:
    from dataflow.transports.ros1.citizen import apply_launch_params
    from support.ros1_tasks import Gauge

    with pytest.raises(ValueError, match=r"_nothing: no task has that property \(the tasks are gauge"):
        apply_launch_params([Gauge()], {"nothing": 1})


def test_use_sim_time_at_launch_makes_the_node_follow_clock(ros: RosMaster) -> None:
    proc, _ = deploy(ros, "clocked", "_use_sim_time:=true")
    try:
        wait_until(lambda: " * /clock [" in ros.tool("rosnode", "info", "/clocked").stdout, timeout=20,
                   message="the node does not follow /clock")
        assert ros.tool("rosparam", "get", "/use_sim_time").returncode != 0  # the node's own, not the global one
    finally:
        stop(proc)


def bag_of(path: Path, start_s: int, seconds: float, period: float = 0.05) -> Path:
    """A ROS 1 bag of ``seconds`` of std_msgs/String on /chatter from ``start_s`` (its time)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    string = store.types["std_msgs/msg/String"]
    with Writer(path) as writer:
        conn = writer.add_connection("/chatter", string.__msgtype__, typestore=store)
        for i in range(int(seconds / period) + 1):
            data = store.serialize_ros1(string(data=f"{i}"), string.__msgtype__)
            writer.write(conn, start_s * 1_000_000_000 + round(i * period * 1e9), data)
    return path


def cycles(ns: str) -> int:
    done = scart("call", "gauge.cycle_count", ns=ns)
    assert done.returncode == 0, done.stderr
    return int(done.stdout)


def test_rosbag_play_clock_drives_the_tasks_periods(ros: RosMaster, tmp_path: Path) -> None:
    bag = bag_of(tmp_path / "three_seconds.bag", 1000, 3.0)
    rosparam(ros, "set", "/use_sim_time", "true")
    proc, ns = deploy(ros, "simulated")  # a period of 0.05 s
    try:
        made = scart("stream", "gauge.heat", "ros1:/gauge/heat", "--type", "sensor_msgs/Temperature",
                     "--option", "latch=true", ns=ns)
        assert made.returncode == 0, made.stderr
        wait_until(lambda: " * /clock [" in ros.tool("rosnode", "info", "/simulated").stdout, timeout=20)
        before = cycles(ns)
        played = ros.tool("rosbag", "play", "--clock", "-r", "2", "-q", str(bag), timeout=60)  # 3 s in 1.5 s
        assert played.returncode == 0, played.stderr
        ran = cycles(ns) - before
        assert 50 <= ran <= 63, f"{ran} cycles of 0.05 s in a 3 s bag played at 2x"  # wall time would give ~30
        echo = ros.tool("rostopic", "echo", "-n", "1", "/gauge/heat", timeout=30)
        secs = int(re.search(r"secs: (\d+)", echo.stdout).group(1))
        assert 1000 <= secs <= 1003, echo.stdout  # stamped in the bag's time, not the system's
        assert cycles(ns) - before == ran  # the bag over, no more /clock: the tasks wait
    finally:
        stop(proc)


def test_the_log_goes_to_rosout_and_the_logger_services_change_it(ros: RosMaster) -> None:
    proc, ns = deploy(ros, "talky")
    key, logger = "/talky/gauge/ceiling", "dataflow.transports.ros1.citizen"
    echo = ros.spawn("rostopic", "echo", "/rosout")
    try:
        wait_until(lambda: key in rosparam(ros, "list").split(), timeout=20)
        listed = ros.tool("rosservice", "call", "/talky/get_loggers")
        assert listed.returncode == 0 and f'name: "{logger}"' in listed.stdout, listed.stdout + listed.stderr

        def level(name: str) -> None:
            done = ros.tool("rosservice", "call", "/talky/set_logger_level", f"{{logger: '{logger}', level: '{name}'}}")
            assert done.returncode == 0, done.stderr

        def refuse(value: str) -> None:  # a warning of that logger, once the value is set back
            rosparam(ros, "set", key, value)
            wait_until(lambda: rosparam(ros, "get", key) == "1.0", timeout=10)

        level("error")
        refuse("98")  # a warning: not published now
        level("warn")
        refuse("99")
        text = echo.read_until("99 refused", timeout=30)
        assert "98 refused" not in text  # /rosout is one ordered stream: 98's record would come first
        record = text[text.rindex("header:"):]
        assert 'name: "/talky"' in record and "level: 4" in record, record
        assert f'msg: "ROS parameter {key}: 99 refused' in record and "function: \"_update\"" in record, record
        assert " - /rosout" in record  # the topics the node publishes
        bad = ros.tool("rosservice", "call", "/talky/set_logger_level", "{logger: 'nobody.here', level: 'debug'}")
        assert bad.returncode != 0 and "no logger 'nobody.here'" in bad.stdout + bad.stderr
    finally:
        echo.stop()
        stop(proc)


def test_a_read_only_node_publishes_and_takes_nothing_from_ros(ros: RosMaster) -> None:
    proc, ns = deploy(ros, "watched", "--ros-read-only")
    try:
        out = scart("stream", "gauge.count", "ros1:/watched/count", ns=ns)
        assert out.returncode == 0, out.stderr
        echo = ros.tool("rostopic", "echo", "-n", "1", "/watched/count", timeout=60)
        assert echo.returncode == 0 and "data: " in echo.stdout, echo.stderr
        into = scart("stream", "gauge.level", "ros1:/watched/level", ns=ns)
        assert into.returncode == 1 and "serves ROS read-only" in into.stderr, into.stderr
        key = "/watched/gauge/ceiling"
        rosparam(ros, "set", key, "2.0")  # a valid value, refused all the same
        wait_until(lambda: rosparam(ros, "get", key) == "1.0", timeout=10)
        assert scart("prop", "get", "gauge", "ceiling", ns=ns).stdout.strip() == "1.0"
        services = ros.tool("rosservice", "list").stdout.split()
        assert "/watched/set_logger_level" not in services and "/watched/get_loggers" not in services
        killed = ros.tool("rosnode", "kill", "/watched")
        assert "/watched" in nodes(ros) and proc.poll() is None, killed.stdout + killed.stderr
    finally:
        said = stop(proc)
    assert "refused (read-only)" in said, said


RESPAWNING = """<?xml version="1.0" encoding="UTF-8"?>
<composite xmlns="http://docs.oasis-open.org/ns/opencsa/sca/200912" xmlns:scart="urn:scart:1.0"
           targetNamespace="urn:scart:test" name="Respawning">
    <component name="gauge">
        <scart:implementation.task class="support.ros1_tasks:Gauge" period="0.05"/>
    </component>
    <scart:stream port="gauge.count" transport="ros1" topic="/phoenix/count" node="phoenix" respawn="true"/>
</composite>
"""


def test_a_composite_whose_node_respawns_registers_again_after_rosnode_kill(ros: RosMaster, tmp_path: Path) -> None:
    composite = tmp_path / "respawning.composite"
    composite.write_text(RESPAWNING)
    proc = subprocess.Popen([sys.executable, "-m", "scart", "run", str(composite), "--ns", f"127.0.0.1:{free_port()}",
                             "--ros-master", ros.uri], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=subprocess_env())
    try:
        wait_until(lambda: "/phoenix" in nodes(ros), timeout=30, message="the composite's node never registered")
        killed = ros.tool("rosnode", "kill", "/phoenix")
        assert killed.returncode == 0, killed.stderr
        wait_until(lambda: " * /phoenix/count [std_msgs/Int64]" in ros.tool("rosnode", "info", "/phoenix").stdout,
                   timeout=20, message="the node never registered again")
        assert proc.poll() is None  # it lives on
    finally:
        said = stop(proc)
    assert "it restarts (respawn)" in said and "restarted, registered again" in said, said
