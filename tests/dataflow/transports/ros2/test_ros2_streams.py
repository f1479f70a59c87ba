"""scart ports as ROS 2 topics (the ``ros2`` transport's streams), judged by an independent
Cyclone DDS peer in another process (``support/ros2_stream_peer.py``, its own IDL types
declaring the ROS 2 names) and by the ``cyclonedds`` command: what a port publishes they
read with its ROS 2 type, what they publish a task reads; QoS from the policy; bad input
refused, counted and named."""

from __future__ import annotations

import math
import threading

import pytest

pytest.importorskip("cyclonedds.domain", reason="cyclonedds is not installed (pip install 'scart[ros2]')")

from support.ros2 import cli, cli_subscribe  # noqa: E402
from pydantic import BaseModel  # noqa: E402

from dataflow import ConnPolicy, Deployer, FlowStatus, InputPort, OutputPort, TaskContext  # noqa: E402
from dataflow.transports import TransportError, load  # noqa: E402
from scart_ros2 import Network, Participant, QoS  # noqa: E402
from support import wait_until  # noqa: E402

pytestmark = pytest.mark.integration


class Joints(BaseModel):
    """A model fed from sensor_msgs/msg/JointState by field names (the rest ignored)."""

    name: list[str]
    position: list[float]


class Source(TaskContext):
    out = OutputPort(float)
    count = OutputPort(int)


class Sink(TaskContext):
    level = InputPort(float, ge=0.0, le=10.0)
    count = InputPort(int)
    joints = InputPort(Joints)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.got: list[object] = []
        self.lock = threading.Lock()

    def drain(self, port: str) -> list[object]:
        """What ``port`` holds now, read (as update_hook would), plus what was read before."""
        for _ in range(10_000):
            flow, value = self.port(port).read()
            if flow is not FlowStatus.NEW_DATA:
                break
            with self.lock:
                self.got.append(value)
        with self.lock:
            return list(self.got)


def evens_only(message: object) -> int:
    """A converter into Sink.count that refuses odd values (as a converter may)."""
    value = int(message.data)  # type: ignore[attr-defined]
    if value % 2:
        raise ValueError(f"{value} is odd")
    return value


@pytest.fixture
def deployer():
    d = Deployer()
    yield d
    for name in list(d.streams()):
        d.unstream(name)
    assert d.streams() == {}
    assert load("ros2").participants() == {}, "the process's participant outlived its last stream"


def _ros2(topic: str, policy: ConnPolicy | None = None) -> ConnPolicy:
    return (policy or ConnPolicy.data()).with_(transport="ros2", topic=topic)


def _note(task: TaskContext, port: str):
    (found,) = next(p for p in task.describe().ports if p.name == port).streams
    return found


def test_an_independent_peer_reads_a_port_and_feeds_one_where_the_task_sees_it(
        domain: int, topic: str, stream_peer, deployer: Deployer) -> None:
    src, sink = deployer.add(Source("src")), deployer.add(Sink("sink"))
    out = deployer.stream("src.out", _ros2(topic + "/out"), {"domain": str(domain)})
    into = deployer.stream("sink.level", _ros2(topic + "/in", ConnPolicy.buffer(10)), {"domain": str(domain)})
    assert (out.source, out.sink, out.transport) == ("src.out", f"ros2:{topic}/out", "ros2")
    assert (into.source, into.sink) == (f"ros2:{topic}/in", "sink.level")
    reader = stream_peer("read", topic + "/out", "Float64")
    values = iter(range(1, 10_000))
    wait_until(lambda: src.out.write(next(values) / 8) and reader.poll("sample", timeout=0.2), timeout=15,
               message="the peer never read the port")
    writer = stream_peer("write", topic + "/in", "Float64", [1.5, math.nan, 11.0, 2.5])
    writer.next_event("acked")
    wait_until(lambda: sink.drain("level") == [1.5, 2.5], timeout=15, message=f"the task saw {sink.got}")
    note = _note(sink, "level")
    assert (note.type_name, note.refused, note.unauthenticated) == ("std_msgs/msg/Float64", 2, True)
    assert "11.0" in note.refusal and "0 <= x <= 10" in note.refusal
    listed = next(lk for lk in deployer.links() if lk.name == into.name)
    assert (listed.samples, listed.dropped) == (4, 2)  # NaN and 11.0: refused, counted
    assert not _note(src, "out").unauthenticated  # what is published is not an input


def test_the_cyclonedds_tool_lists_and_prints_a_stream_with_its_ros2_type(
        domain: int, topic: str, deployer: Deployer) -> None:
    src = deployer.add(Source("src"))
    deployer.stream("src.out", _ros2(topic), {"domain": str(domain)})
    deployer.stream("src.count", _ros2(topic + "_n"), {"domain": str(domain), "type": "std_msgs/msg/Int32"})
    listing = cli("ls", "--id", str(domain), "--runtime", "2", "--topic", "rt" + topic + ".*").stdout
    assert "rt" + topic in listing and "std_msgs::msg::dds_::Float64_" in listing, listing
    assert "rt" + topic + "_n" in listing and "std_msgs::msg::dds_::Int32_" in listing, listing
    ros = load("ros2").participants()[domain]

    def write() -> bool:
        src.out.write(41.5)
        return any(p.matched() for p in ros._endpoints if getattr(p, "topic", "") == topic)
    out, err = cli_subscribe(domain, "rt" + topic, write)
    assert "Float64_(data=41.5)" in out, (out, err)


def test_buffer_n_is_keep_last_n_and_latch_hands_them_to_a_late_joiner(
        domain: int, topic: str, stream_peer, deployer: Deployer) -> None:
    src = deployer.add(Source("src"))
    deployer.stream("src.count", _ros2(topic, ConnPolicy.buffer(3)), {"domain": str(domain), "latch": "true"})
    for i in range(6):
        src.count.write(i)
    late = stream_peer("read", topic, "Int64", latched=True, depth=10)
    assert [late.next_event("sample")["data"] for _ in range(3)] == [3, 4, 5]
    src.count.write(99)
    assert late.next_event("sample")["data"] == 99


def test_data_is_not_latched_a_late_joiner_gets_no_stale_value(
        domain: int, topic: str, stream_peer, deployer: Deployer) -> None:
    src = deployer.add(Source("src"))
    deployer.stream("src.count", _ros2(topic, ConnPolicy.data()), {"domain": str(domain)})  # volatile, as rclpy's
    for i in range(3):
        src.count.write(i)
    late = stream_peer("read", topic, "Int64")
    written = iter(range(3, 1000))

    def heard() -> bool:
        src.count.write(next(written))
        return late.poll("sample", 0.05) is not None

    wait_until(heard, timeout=30, message="the late reader never heard the stream")
    assert late.events[-1]["data"] >= 3  # never the stale 2, written before it joined


def test_best_effort_on_request_and_reliable_readers_then_do_not_match(
        domain: int, topic: str, deployer: Deployer) -> None:
    deployer.add(Source("src"))
    deployer.stream("src.out", _ros2(topic, ConnPolicy.data(init=False)),
                    {"domain": str(domain), "best_effort": "true"})
    with Participant(domain) as other:
        lax = other.subscribe(topic, "std_msgs/msg/Float64", lambda m: None, QoS.data(best_effort=True))
        strict = other.subscribe(topic, "std_msgs/msg/Float64", lambda m: None, QoS.data())
        wait_until(lax.matched, timeout=15, message="a best-effort reader never matched")
        assert strict.matched() == 0


def test_a_message_that_does_not_convert_is_refused_counted_and_named(
        domain: int, topic: str, stream_peer, deployer: Deployer) -> None:
    sink = deployer.add(Sink("sink"))
    deployer.stream("sink.count", _ros2(topic, ConnPolicy.buffer(10)),
                    {"domain": str(domain), "converter": f"{__name__}:evens_only"})
    writer = stream_peer("write", topic, "Int64", [2, 3, 4])
    writer.next_event("acked")
    wait_until(lambda: sink.drain("count") == [2, 4], timeout=15, message=f"the task saw {sink.got}")
    note = _note(sink, "count")
    assert note.refused == 1 and "3 is odd" in note.refusal and "does not convert" in note.refusal


def test_a_sample_written_as_its_stream_closes_is_unsent_not_refused(domain: int, topic: str,
                                                                      deployer: Deployer) -> None:
    src = deployer.add(Source("src"))
    made = deployer.stream("src.out", _ros2(topic, ConnPolicy.buffer(10)), {"domain": str(domain)})
    stream = deployer.streams()[made.name]
    src.out.write(1.0)
    stream._stream._pub.close()  # noqa: SLF001 - the race of a stop: the publisher goes first
    src.out.write(2.0)
    note = _note(src, "out")
    assert (note.refused, note.refusal) == (0, "")  # not a refusal (it used to say "sample 2: None")
    assert stream.writer.pending == 1  # kept, as its policy says, ...
    deployer.unstream(made.name)
    assert (stream.writer.sent, stream.writer.unsent, stream.writer.dropped) == (1, 1, 1)  # ... then counted unsent


def test_a_value_a_message_cannot_hold_is_refused_counted_and_named(
        domain: int, topic: str, deployer: Deployer) -> None:
    src = deployer.add(Source("src"))
    made = deployer.stream("src.count", _ros2(topic, ConnPolicy.buffer(10)),
                           {"domain": str(domain), "type": "std_msgs/msg/Int8"})
    got: list[int] = []
    with Participant(domain) as other:
        sub = other.subscribe(topic, "std_msgs/msg/Int8", lambda m: got.append(m.data), QoS.buffer(10))
        wait_until(sub.matched, timeout=15)
        for value in (5, 300, 6):
            src.count.write(value)
        wait_until(lambda: got == [5, 6], timeout=15, message=f"read {got}")
    note = _note(src, "count")
    assert note.refused == 1 and "300" in note.refusal and "out of range" in note.refusal
    assert next(lk for lk in deployer.links() if lk.name == made.name).dropped == 1


def test_a_model_is_fed_by_field_names_and_malformed_samples_are_counted(
        domain: int, peer, deployer: Deployer) -> None:
    sink = deployer.add(Sink("sink"))
    deployer.stream("sink.joints", _ros2("/peer/bad", ConnPolicy.buffer(10)),
                    {"domain": str(domain), "type": "sensor_msgs/msg/JointState"})
    peer("bad")  # truncated CDR and bad UTF-8, then a good sample, every 100 ms
    wait_until(lambda: sink.drain("joints") and _note(sink, "joints").refused >= 2, timeout=15,
               message=f"got {sink.got}, {_note(sink, 'joints')}")
    assert all(isinstance(j, Joints) for j in sink.got)
    assert "malformed" in _note(sink, "joints").refusal


def test_a_stream_is_refused_before_anything_is_made_with_both_types(domain: int, topic: str) -> None:
    d = Deployer()
    d.add(Source("src"))
    d.add(Sink("sink"))
    with pytest.raises(TransportError, match=r"port sink\.count \(int64\).*Float64\.data: int and float64 \(a float never narrows"):
        d.stream("sink.count", _ros2(topic), {"domain": str(domain), "type": "std_msgs/msg/Float64"})
    with pytest.raises(TransportError, match="no default ROS 2 type"):
        d.stream("sink.joints", _ros2(topic), {"domain": str(domain)})
    with pytest.raises(TransportError, match="unknown option"):
        d.stream("src.out", _ros2(topic), {"domain": str(domain), "qos": "fast"})
    with pytest.raises(TransportError, match="not imported"):
        d.stream("src.out", _ros2(topic), {"domain": str(domain), "converter": "no_such_module:f"})
    with pytest.raises(TransportError, match="give insecure=true"):
        d.stream("src.out", _ros2(topic), {"domain": str(domain), "interface": "eth0"})
    assert d.links() == [] and load("ros2").participants() == {}  # nothing joined, no participant made


def test_a_sample_larger_than_the_bound_never_reaches_the_process(domain: int, stream_peer) -> None:
    other = domain % 232 + 1  # a domain of its own: Cyclone configures a domain once per process
    got: list[int] = []
    with Participant(other, network=Network.loopback(max_sample_bytes=64 * 1024)) as ros:
        ros.subscribe("/big", "sensor_msgs/msg/JointState", lambda m: got.append(len(m.name)), QoS.buffer(10))
        big = {"name": {"$repeat": ["j" * 100, 2000]}}  # about 220 kB of CDR
        stream_peer("write", "/big", "JointState", [big, {"name": ["small"]}], on=other).next_event("wrote")
        wait_until(lambda: got, timeout=15, message="the small sample never came")
    assert got == [1]


def test_use_sim_time_puts_the_tasks_on_clock(domain: int, topic: str, deployer: Deployer) -> None:
    source = deployer.add(Source("src"))
    transport = load("ros2")
    transport.attach(deployer)  # the process's ROS 2 node speaks for these tasks
    try:
        deployer.stream("src.count", _ros2(topic), {"domain": str(domain)})
        node = next(iter(transport.participants().values())).node
        with Participant(domain) as ros:
            client = ros.client(f"/{node.name}/set_parameters", "rcl_interfaces/srv/SetParameters")

            def sim_time(on: bool):
                asked = {"parameters": [{"name": "use_sim_time", "value": {"type": 1, "bool_value": on}}]}
                return wait_until(lambda: _reply(client, asked), timeout=20, message="no answer").results[0]

            assert sim_time(True).successful and source.clock.simulated  # one clock for every task
            clock = ros.publisher("/clock", "rosgraph_msgs/msg/Clock", QoS.data(best_effort=True))

            def at(sec: int) -> bool:
                clock.publish({"clock": {"sec": sec, "nanosec": 5}})
                return source.clock.now_ns() == sec * 1_000_000_000 + 5

            wait_until(lambda: at(100), timeout=20, message="/clock never reached the task's clock")
            wait_until(lambda: at(101), timeout=10)  # it follows
            assert sim_time(False).successful and not source.clock.simulated and deployer.clock is source.clock
    finally:
        transport.detach(deployer)


def _reply(client, request: dict):
    try:
        return client.call(request, timeout=1.0)
    except TimeoutError:
        return None
