"""An independent ROS 2-speaking Cyclone DDS peer of scart's ``ros2`` streams, run as a
subprocess by their tests.

Written from the ROS 2 conventions alone (no scart import; the IDL types it shares with
``ros2_peer.py`` come from there): its own IDL types declaring
the ROS 2 DDS type names (``std_msgs::msg::dds_::Float64_``...), ``rt/`` topics, rmw's
default QoS (reliable, volatile, keep-last). It joins the domain given with the
``CYCLONEDDS_URI`` configuration the tests give it (loopback only) and prints one JSON
line per event, ``ready`` first.

``python ros2_stream_peer.py read DOMAIN TOPIC TYPE [--latched] [--depth N] [--seconds S]``
prints each sample of ``rt<TOPIC>`` (``{"event": "sample", ...fields}``).

``python ros2_stream_peer.py write DOMAIN TOPIC TYPE JSON [--seconds S]`` waits for a
reader, writes each value of the JSON list (a number for Float64/Int64, an object of
fields for JointState, a list (or ``{"data", "dim"}``) for a multi-array, ``{"height",
"width", "encoding", "channels", "seed"}`` for an Image of :func:`pattern` bytes;
``{"$repeat": [item, n]}`` stands for ``n`` items), 20 ms apart, prints ``wrote``, then
waits for the readers to acknowledge them. ``TYPE``: ``Float64``, ``Int64``,
``JointState``, ``Float64MultiArray``, ``Float32MultiArray``, ``Image`` (an image read is
printed as its fields and the SHA-256 of its data, not its bytes).
"""

# (no "from __future__ import annotations": cyclonedds reads the annotations as objects)

import argparse
import hashlib
import json
import sys
import time
from dataclasses import dataclass

from cyclonedds.core import ReadCondition, WaitSet
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl import types as t
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration
from ros2_peer import ANY, Float64_, Header_, JointState_, Time_, say  # the other peer's IDL types (this folder)


@dataclass
class Int64_(IdlStruct, typename="std_msgs::msg::dds_::Int64_"):
    data: t.int64


@dataclass
class MultiArrayDimension_(IdlStruct, typename="std_msgs::msg::dds_::MultiArrayDimension_"):
    label: str
    size: t.uint32
    stride: t.uint32


@dataclass
class MultiArrayLayout_(IdlStruct, typename="std_msgs::msg::dds_::MultiArrayLayout_"):
    dim: t.sequence[MultiArrayDimension_]
    data_offset: t.uint32


@dataclass
class Float64MultiArray_(IdlStruct, typename="std_msgs::msg::dds_::Float64MultiArray_"):
    layout: MultiArrayLayout_
    data: t.sequence[t.float64]


@dataclass
class Float32MultiArray_(IdlStruct, typename="std_msgs::msg::dds_::Float32MultiArray_"):
    layout: MultiArrayLayout_
    data: t.sequence[t.float32]


@dataclass
class Image_(IdlStruct, typename="sensor_msgs::msg::dds_::Image_"):
    header: Header_
    height: t.uint32
    width: t.uint32
    encoding: str
    is_bigendian: t.uint8
    step: t.uint32
    data: t.sequence[t.uint8]


TYPES = {"Float64": Float64_, "Int64": Int64_, "JointState": JointState_, "Float64MultiArray": Float64MultiArray_,
         "Float32MultiArray": Float32MultiArray_, "Image": Image_}
ARRAYS = (Float64MultiArray_, Float32MultiArray_)


def pattern(size: int, seed: int) -> bytes:
    """``size`` bytes that the test makes too: byte i is (i * seed + seed) % 251."""
    return bytes((i * seed + seed) % 251 for i in range(251)) * (size // 251) + \
        bytes((i * seed + seed) % 251 for i in range(size % 251))


def qos(depth: int, latched: bool) -> Qos:
    return Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(depth),
               Policy.Durability.TransientLocal if latched else Policy.Durability.Volatile)


def fields(sample: object) -> dict:
    if isinstance(sample, JointState_):
        return {"sec": sample.header.stamp.sec, "nanosec": sample.header.stamp.nanosec,
                "frame_id": sample.header.frame_id, "name": list(sample.name), "position": list(sample.position),
                "velocity": list(sample.velocity), "effort": list(sample.effort)}
    if isinstance(sample, Image_):
        return {"height": sample.height, "width": sample.width, "encoding": sample.encoding, "step": sample.step,
                "is_bigendian": sample.is_bigendian, "frame_id": sample.header.frame_id, "bytes": len(sample.data),
                "sha256": hashlib.sha256(bytes(sample.data)).hexdigest()}
    if isinstance(sample, ARRAYS):
        return {"data": list(sample.data), "dim": [[d.label, d.size, d.stride] for d in sample.layout.dim],
                "data_offset": sample.layout.data_offset}
    return {"data": sample.data}


def read(dp: DomainParticipant, topic: Topic, args: argparse.Namespace) -> None:
    reader = DataReader(dp, topic, qos=qos(args.depth, args.latched))
    waitset = WaitSet(dp)
    waitset.attach(ReadCondition(reader, ANY))
    say(event="ready")
    deadline = time.monotonic() + args.seconds
    while time.monotonic() < deadline:
        waitset.wait(duration(milliseconds=100))
        for sample in reader.take(N=100):
            if sample.sample_info.valid_data:
                say(event="sample", **fields(sample))


def expand(value: object) -> object:
    """``{"$repeat": [item, n]}`` as ``[item] * n`` (large samples without a long argv)."""
    if isinstance(value, dict):
        if set(value) == {"$repeat"}:
            item, count = value["$repeat"]
            return [item] * count
        return {k: expand(v) for k, v in value.items()}
    return value


def make(cls: type, value: object) -> object:
    value = expand(value)
    if cls is JointState_:
        v = dict(value)
        header = Header_(stamp=Time_(sec=v.pop("sec", 0), nanosec=v.pop("nanosec", 0)), frame_id=v.pop("frame_id", ""))
        return JointState_(header=header, **{k: v.get(k, []) for k in ("name", "position", "velocity", "effort")})
    if cls in ARRAYS:  # a list, or {"data": [...], "dim": [[label, size, stride], ...]}
        v = value if isinstance(value, dict) else {"data": value}
        dims = [MultiArrayDimension_(label=a, size=b, stride=c) for a, b, c in v.get("dim", [])]
        return cls(layout=MultiArrayLayout_(dim=dims, data_offset=0), data=list(v["data"]))
    if cls is Image_:  # {"height", "width", "encoding", "channels", "seed"}: pattern() bytes
        v = dict(value)
        step = v["width"] * v["channels"]
        return Image_(header=Header_(stamp=Time_(sec=1, nanosec=2), frame_id="camera"), height=v["height"],
                      width=v["width"], encoding=v["encoding"], is_bigendian=0, step=step,
                      data=pattern(step * v["height"], v["seed"]))
    return cls(data=value)


def write(dp: DomainParticipant, topic: Topic, cls: type, args: argparse.Namespace) -> None:
    writer = DataWriter(dp, topic, qos=qos(args.depth, args.latched))
    say(event="ready")
    deadline = time.monotonic() + args.seconds
    while not writer.get_matched_subscriptions():
        if time.monotonic() > deadline:
            say(event="unmatched")
            return
        time.sleep(0.01)
    for value in json.loads(args.json):
        writer.write(make(cls, value))
        time.sleep(0.02)
    say(event="wrote")
    writer.wait_for_acks(duration(seconds=10))
    say(event="acked")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("mode", choices=("read", "write"))
    parser.add_argument("domain", type=int)
    parser.add_argument("topic")
    parser.add_argument("type", choices=sorted(TYPES))
    parser.add_argument("json", nargs="?", default="[]")
    parser.add_argument("--latched", action="store_true")
    parser.add_argument("--depth", type=int, default=10)
    parser.add_argument("--seconds", type=float, default=60.0)
    args = parser.parse_args()
    dp = DomainParticipant(args.domain)
    cls = TYPES[args.type]
    topic = Topic(dp, "rt" + args.topic, cls)
    if args.mode == "read":
        read(dp, topic, args)
    else:
        write(dp, topic, cls, args)


if __name__ == "__main__":
    sys.exit(main())
