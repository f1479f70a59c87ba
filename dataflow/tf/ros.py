"""A frame buffer joined to ROS's ``/tf`` and ``/tf_static`` (tf2_ros' ``TransformListener``
and broadcasters in one), over the process's ROS 1 node or ROS 2 participant.

:class:`Ros1Frames` and :class:`Ros2Frames` each subscribe to both topics and publish on
them: what the buffer gets from its own process (tasks, a composite's frames, the other
ROS) goes out, each :meth:`~dataflow.tf.FrameBuffer.publish` as one ``tf2_msgs``
``TFMessage``; every static transform of the process is sent again, all together, each
time one changes, on a latched (ROS 1) or transient-local keep-last-1 (ROS 2) writer,
as tf2_ros' ``StaticTransformBroadcaster`` does. What arrives goes into the buffer
through :meth:`~dataflow.tf.FrameBuffer.receive`: a refused transform (NaN, a rotation
too far from unit, a second parent, a cycle) is counted and said once. What this process
sent comes back from its own subscription and changes nothing (the same values at the
same stamp).

QoS on ROS 2 are tf2_ros' own: ``/tf`` reliable keep-last 100 (volatile), ``/tf_static``
reliable transient-local (keep-last 1 written, 100 read). Both go through the public
face of the transports (``acquire``/``release`` of the process's node or participant),
so they share the process's one node or participant with its streams and services.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Mapping
from typing import Any, Protocol

from dataflow.transports import TransportError, load

from .buffer import FrameBuffer
from .transform import Transform

__all__ = ["RosFrames", "Ros1Frames", "Ros2Frames", "TF", "TF_STATIC"]

log = logging.getLogger(__name__)

TF, TF_STATIC = "/tf", "/tf_static"
_DEPTH = 100  #: tf2_ros' queue and history depth on /tf


class _Closing(Protocol):
    def close(self) -> None: ...


class RosFrames:
    """What both ROS bridges share: the buffer, what goes out, what comes in. ``close``
    is idempotent; after it nothing is sent."""

    origin = ""

    def __init__(self, buffer: FrameBuffer) -> None:
        self.buffer = buffer
        self._transport: Any = None  # a ros1 or ros2 transport: duck-typed, loaded by name
        self._lock = threading.Lock()
        self._closed = False
        self.received = 0  #: TFMessages received
        self.sent = 0  #: TFMessages sent

    def _start(self) -> None:
        """Send the statics held now, then follow what the buffer stores."""
        if self.buffer.statics(excluding=self.origin):
            self._send_statics()
        self._unhook = self.buffer.on_publish(self._on_publish, self.origin)

    def _on_publish(self, transforms: list[Transform], static: bool, origin: str) -> None:
        if self._closed:
            return
        if static:
            self._send_statics()
        else:
            self._send(TF, transforms)

    def _send_statics(self) -> None:
        """Every static transform of this process (not those this ROS gave), in one message."""
        self._send(TF_STATIC, self.buffer.statics(excluding=self.origin))

    def _on_message(self, message: Any, static: bool) -> None:  # a rosbags TFMessage
        """A TFMessage from ROS (the node's or participant's thread): into the buffer."""
        self.received += 1
        try:
            transforms = [_transform(t) for t in message.transforms]
        except (AttributeError, TypeError, ValueError) as exc:
            log.warning("%s %s: a malformed TFMessage: %s", self.origin, TF_STATIC if static else TF, exc)
            return
        self.buffer.receive(transforms, static=static, authority=self.origin, origin=self.origin)

    def _send(self, topic: str, transforms: list[Transform]) -> None:
        raise NotImplementedError

    def close(self) -> None:
        """Stop following the buffer and leave both topics (idempotent)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        unhook = getattr(self, "_unhook", None)
        if unhook is not None:
            unhook()
        self._close()

    def _close(self) -> None:
        raise NotImplementedError


def _transform(t: Any) -> Transform:
    """A rosbags ``geometry_msgs/TransformStamped`` as a :class:`Transform` (stamp exact)."""
    stamp = t.header.stamp
    tr, rot = t.transform.translation, t.transform.rotation
    return Transform(t.header.frame_id, t.child_frame_id, (tr.x, tr.y, tr.z), (rot.x, rot.y, rot.z, rot.w),
                     int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec))


def _fields(transforms: list[Transform], seq: bool) -> dict[str, object]:
    """A ``tf2_msgs/TFMessage``'s fields (ROS 1's header has a ``seq``, ROS 2's none)."""
    out = []
    for t in transforms:
        sec, nanosec = divmod(t.stamp_ns, 1_000_000_000)
        header: dict[str, object] = {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": t.frame_id}
        if seq:
            header["seq"] = 0
        x, y, z = t.translation
        qx, qy, qz, qw = t.rotation
        out.append({"header": header, "child_frame_id": t.child_frame_id,
                    "transform": {"translation": {"x": x, "y": y, "z": z},
                                  "rotation": {"x": qx, "y": qy, "z": qz, "w": qw}}})
    return {"transforms": out}


class Ros1Frames(RosFrames):
    """``buffer`` joined to ROS 1's ``/tf`` and ``/tf_static`` through the process's node
    (``options``: the ``ros1`` transport's node options, ``master``, ``node``...). Raises
    :class:`TransportError` when the node cannot be had."""

    origin = "ros1"
    TYPE = "tf2_msgs/TFMessage"
    #: tf2_msgs/TFMessage.msg, which rosbags' Noetic store lacks (its md5sum is ROS's: 94810edd...)
    DEFINITION = "geometry_msgs/TransformStamped[] transforms\n"

    def __init__(self, buffer: FrameBuffer, options: Mapping[str, str] | None = None) -> None:
        super().__init__(buffer)
        transport: Any = load("ros1")
        if not hasattr(transport, "acquire"):
            raise TransportError(f"transport 'ros1' is a {type(transport).__qualname__}, not scart's")
        self._transport = transport
        self.node = transport.acquire(dict(options or {}))
        self._parts: list[_Closing] = []
        try:
            if self.TYPE not in self.node.types.names():
                self.node.types.add_msg(self.TYPE, self.DEFINITION)
            self._pub = self.node.advertise(TF, self.TYPE, queue_size=_DEPTH)
            self._parts.append(self._pub)
            self._static_pub = self.node.advertise(TF_STATIC, self.TYPE, latch=True, queue_size=1)
            self._parts.append(self._static_pub)
            self._parts.append(self.node.subscribe(TF, self.TYPE, lambda m: self._on_message(m, False)))
            self._parts.append(self.node.subscribe(TF_STATIC, self.TYPE, lambda m: self._on_message(m, True)))
            self._start()
        except (ValueError, RuntimeError) as exc:  # /tf taken in this node already, the node closed
            self._close()
            raise TransportError(f"ros1: {exc}") from None
        except BaseException:
            self._close()
            raise

    def _send(self, topic: str, transforms: list[Transform]) -> None:
        pub = self._static_pub if topic == TF_STATIC else self._pub
        if topic == TF and not pub.wanted:
            return
        pub.publish(pub.type.new(**_fields(transforms, seq=True)))
        self.sent += 1

    def _close(self) -> None:
        for part in reversed(self._parts):
            part.close()
        self._parts = []
        self._transport.release(self.node)


class Ros2Frames(RosFrames):
    """``buffer`` joined to ROS 2's ``/tf`` and ``/tf_static`` (DDS ``rt/tf``,
    ``rt/tf_static``) through the process's participant (``options``: the ``ros2``
    transport's ``domain``, ``insecure``, ``interface``, ``peers``). Raises
    :class:`TransportError` (no Cyclone DDS, a domain open otherwise)."""

    origin = "ros2"
    TYPE = "tf2_msgs/msg/TFMessage"

    def __init__(self, buffer: FrameBuffer, options: Mapping[str, str] | None = None) -> None:
        super().__init__(buffer)
        transport: Any = load("ros2")
        if not hasattr(transport, "acquire"):
            raise TransportError(f"transport 'ros2' is a {type(transport).__qualname__}, not scart's")
        self._transport = transport
        try:
            from scart_ros2 import QoS, Ros2Error

            where = transport.where(dict(options or {}))
        except ImportError as exc:
            raise TransportError(str(exc)) from None
        except ValueError as exc:
            raise TransportError(f"ros2: {exc}") from None
        self.participant = self._transport.acquire(where)
        self._parts: list[_Closing] = []
        try:
            self._pub = self.participant.publisher(TF, self.TYPE, QoS.buffer(_DEPTH))
            self._parts.append(self._pub)
            self._static_pub = self.participant.publisher(TF_STATIC, self.TYPE, QoS.data(latching=True))
            self._parts.append(self._static_pub)
            self._parts.append(self.participant.subscribe(TF, self.TYPE, lambda m: self._on_message(m, False),
                                                          QoS.buffer(_DEPTH)))
            self._parts.append(self.participant.subscribe(TF_STATIC, self.TYPE, lambda m: self._on_message(m, True),
                                                          QoS.buffer(_DEPTH, latching=True)))
            self._start()
        except Ros2Error as exc:
            self._close()
            raise TransportError(f"ros2: {exc}") from None
        except BaseException:
            self._close()
            raise

    def _send(self, topic: str, transforms: list[Transform]) -> None:
        pub = self._static_pub if topic == TF_STATIC else self._pub
        if pub.publish(_fields(transforms, seq=False)):
            self.sent += 1

    def _close(self) -> None:
        for part in reversed(self._parts):
            part.close()
        self._parts = []
        self._transport.release(self.participant)
