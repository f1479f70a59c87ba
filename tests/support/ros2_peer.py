"""An independent ROS 2-speaking Cyclone DDS peer, run as a subprocess by the ROS 2 tests.

Written from the ROS 2 conventions alone (no scart import): its own IDL types declaring
the ROS 2 DDS type names, ``rt/`` topics, and rmw_cyclonedds' service request header.
It joins the domain given by ``CYCLONEDDS_URI`` (the tests give it the loopback-only
configuration) and prints one JSON line per event; ``ready`` first.

Modes (``python ros2_peer.py MODE DOMAIN [SECONDS]``):

* ``relay``: reads ``rt/peer/in`` (Float64) and writes each value + 1 to ``rt/peer/out``;
  reads ``rt/peer/js_in`` (JointState) and writes it back on ``rt/peer/js_out`` with
  ``frame_id`` prefixed by ``peer:`` and positions doubled.
* ``bad``: writes ``rt/peer/bad`` JointState samples whose CDR is truncated or whose
  ``frame_id`` is not UTF-8, then one good sample, every 100 ms.
* ``client``: calls ``/peer/add`` (example_interfaces/srv/AddTwoInts) with a=20, b=22
  once the service is matched, and prints the reply's header and sum.
* ``graph``: reads ``ros_discovery_info`` (rmw_dds_common's ParticipantEntitiesInfo,
  Jazzy's 16-byte Gid) and prints each participant's nodes with their GIDs in hex.
* ``server``: answers ``/peer/times`` (example_interfaces/srv/AddTwoInts) with a × b,
  echoing each request's header as rmw_cyclonedds does, and prints each request.
"""

# (no "from __future__ import annotations": cyclonedds reads the annotations as objects)

import json
import struct
import sys
import time
from dataclasses import dataclass

from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState, WaitSet
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl import types as t
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration


@dataclass
class Float64_(IdlStruct, typename="std_msgs::msg::dds_::Float64_"):
    data: t.float64


@dataclass
class Time_(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: t.int32
    nanosec: t.uint32


@dataclass
class Header_(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time_
    frame_id: str


@dataclass
class JointState_(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    header: Header_
    name: t.sequence[str]
    position: t.sequence[t.float64]
    velocity: t.sequence[t.float64]
    effort: t.sequence[t.float64]


@dataclass
class AddTwoInts_Request_(IdlStruct, typename="example_interfaces::srv::dds_::AddTwoInts_Request_"):
    guid: t.uint64  # rmw_cyclonedds' cdds_request_header_t, then the request
    seq: t.int64
    a: t.int64
    b: t.int64


@dataclass
class AddTwoInts_Response_(IdlStruct, typename="example_interfaces::srv::dds_::AddTwoInts_Response_"):
    guid: t.uint64
    seq: t.int64
    sum: t.int64


@dataclass
class Gid_(IdlStruct, typename="rmw_dds_common::msg::dds_::Gid_"):
    data: t.array[t.uint8, 16]


@dataclass
class NodeEntitiesInfo_(IdlStruct, typename="rmw_dds_common::msg::dds_::NodeEntitiesInfo_"):
    node_namespace: t.bounded_str[256]
    node_name: t.bounded_str[256]
    reader_gid_seq: t.sequence[Gid_]
    writer_gid_seq: t.sequence[Gid_]


@dataclass
class ParticipantEntitiesInfo_(IdlStruct, typename="rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"):
    gid: Gid_
    node_entities_info_seq: t.sequence[NodeEntitiesInfo_]


QOS = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(10),
          Policy.Durability.Volatile)
ANY = SampleState.Any | ViewState.Any | InstanceState.Any


def say(**event: object) -> None:
    print(json.dumps(event), flush=True)


def write_when_matched(writer: DataWriter, sample: object, seconds: float = 10) -> None:
    """Write once the writer sees a reader: DDS discovery is one-sided, so the test's reader
    having matched this writer does not mean this writer has matched it yet (a volatile
    sample written before would reach no one)."""
    deadline = time.monotonic() + seconds
    while not writer.get_matched_subscriptions() and time.monotonic() < deadline:
        time.sleep(0.01)
    writer.write(sample)


def relay(dp: DomainParticipant, seconds: float) -> None:
    f_in = DataReader(dp, Topic(dp, "rt/peer/in", Float64_), qos=QOS)
    f_out = DataWriter(dp, Topic(dp, "rt/peer/out", Float64_), qos=QOS)
    js_in = DataReader(dp, Topic(dp, "rt/peer/js_in", JointState_), qos=QOS)
    js_out = DataWriter(dp, Topic(dp, "rt/peer/js_out", JointState_), qos=QOS)
    waitset = WaitSet(dp)
    for reader in (f_in, js_in):
        waitset.attach(ReadCondition(reader, ANY))
    say(event="ready")
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        waitset.wait(duration(milliseconds=200))
        for sample in f_in.take(N=100):
            if sample.sample_info.valid_data:
                say(event="float64", data=sample.data)
                write_when_matched(f_out, Float64_(data=sample.data + 1))
        for sample in js_in.take(N=100):
            if sample.sample_info.valid_data:
                say(event="joint_state", frame_id=sample.header.frame_id, sec=sample.header.stamp.sec,
                    nanosec=sample.header.stamp.nanosec, name=list(sample.name),
                    position=list(sample.position), velocity=list(sample.velocity))
                sample.header.frame_id = "peer:" + sample.header.frame_id
                sample.position = [2 * p for p in sample.position]
                write_when_matched(js_out, sample)


def raw(data: bytes) -> JointState_:
    """A sample whose bytes are ``data`` as they are (DataWriter.write calls serialize())."""
    sample = JointState_(Header_(Time_(0, 0), ""), [], [], [], [])
    sample.serialize = lambda **_: data
    return sample


def bad(dp: DomainParticipant, seconds: float) -> None:
    writer = DataWriter(dp, Topic(dp, "rt/peer/bad", JointState_), qos=QOS)
    good = JointState_(Header_(Time_(1, 2), "good"), ["j"], [1.0], [], [])
    truncated = good.serialize()[:14]
    not_utf8 = b"\x00\x01\x00\x00" + struct.pack("<iiI", 1, 2, 3) + b"\xff\xfe\x00" + b"\x00" + b"\x00" * 16
    say(event="ready")
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        for sample in (raw(truncated), raw(not_utf8), good):
            try:
                writer.write(sample)
            except Exception as exc:  # Cyclone checks the CDR it is given: a truncated one is refused here
                say(event="write_refused", error=str(exc))
        time.sleep(0.1)


def client(dp: DomainParticipant, seconds: float) -> None:
    user_data = Policy.Userdata(data=b"clientid=01.2.3.4.5.6.7.8.9.a.b.c.d.e.f.10;")
    qos = Qos(*QOS, user_data)
    writer = DataWriter(dp, Topic(dp, "rq/peer/addRequest", AddTwoInts_Request_), qos=qos)
    # rmw_cyclonedds announces no XTypes type and matches by type name alone: read as leniently
    lenient = Qos(*qos, Policy.TypeConsistency.AllowTypeCoercion(ignore_member_names=True))
    reader = DataReader(dp, Topic(dp, "rr/peer/addReply", AddTwoInts_Response_), qos=lenient)
    guid = writer.get_instance_handle() & 0xFFFF_FFFF_FFFF_FFFF  # uint64 on the wire
    say(event="ready", guid=guid)
    deadline = time.monotonic() + seconds
    while not (writer.get_matched_subscriptions() and reader.get_matched_publications()):
        if time.monotonic() > deadline:
            return
        time.sleep(0.01)
    writer.write(AddTwoInts_Request_(guid=guid, seq=7, a=20, b=22))
    while time.monotonic() < deadline:
        for reply in reader.take(N=10):
            if reply.sample_info.valid_data:
                say(event="reply", guid=reply.guid, seq=reply.seq, sum=reply.sum, mine=reply.guid == guid)
                return
        time.sleep(0.01)


def server(dp: DomainParticipant, seconds: float) -> None:
    user_data = Policy.Userdata(data=b"serviceid=02.2.3.4.5.6.7.8.9.a.b.c.d.e.f.10;")
    lenient = Qos(*QOS, user_data, Policy.TypeConsistency.AllowTypeCoercion(ignore_member_names=True))
    reader = DataReader(dp, Topic(dp, "rq/peer/timesRequest", AddTwoInts_Request_), qos=lenient)
    writer = DataWriter(dp, Topic(dp, "rr/peer/timesReply", AddTwoInts_Response_), qos=Qos(*QOS, user_data))
    waitset = WaitSet(dp)
    waitset.attach(ReadCondition(reader, ANY))
    say(event="ready")
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        waitset.wait(duration(milliseconds=200))
        for request in reader.take(N=10):
            if request.sample_info.valid_data:
                say(event="request", guid=request.guid, seq=request.seq, a=request.a, b=request.b)
                writer.write(AddTwoInts_Response_(guid=request.guid, seq=request.seq, sum=request.a * request.b))


def graph(dp: DomainParticipant, seconds: float) -> None:
    qos = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(10),
              Policy.Durability.TransientLocal)
    reader = DataReader(dp, Topic(dp, "ros_discovery_info", ParticipantEntitiesInfo_), qos=qos)
    say(event="ready")
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        for info in reader.take(N=10):
            if info.sample_info.valid_data:
                say(event="participant", gid=bytes(info.gid.data).hex(), nodes=[
                    {"namespace": n.node_namespace, "name": n.node_name,
                     "readers": [bytes(g.data).hex() for g in n.reader_gid_seq],
                     "writers": [bytes(g.data).hex() for g in n.writer_gid_seq]}
                    for n in info.node_entities_info_seq])
        time.sleep(0.02)


def main() -> None:
    mode, domain = sys.argv[1], int(sys.argv[2])
    seconds = float(sys.argv[3]) if len(sys.argv) > 3 else 30.0
    dp = DomainParticipant(domain)
    {"relay": relay, "bad": bad, "client": client, "server": server, "graph": graph}[mode](dp, seconds)


if __name__ == "__main__":
    main()
