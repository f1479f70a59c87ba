"""Frames: a transform tree looked up in time, that ROS's tf2 agrees with.

The story — publish, look up (now, in the past, between two stamps), join ROS::

    import time
    from dataflow.tf import FrameBuffer, Transform

    frames = FrameBuffer(cache_time=10.0)                    # 10 s of history, as tf2
    frames.publish(Transform.from_rpy("base_link", "laser", (0.3, 0.0, 0.2)), static=True)
    frames.publish(Transform("odom", "base_link", (1.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0),
                             stamp_ns=time.time_ns()))
    pose = frames.lookup("odom", "laser", 0.0)              # now: the newest time the path has
    pose = frames.lookup("odom", "laser", t)                # interpolated between two stamps
    pose = frames.lookup("odom", t1, "laser", t0, "map")    # where the laser was at t0, seen at t1
    pose.translation, pose.rotation, pose.rpy, pose.apply((1.0, 0.0, 0.0))

In a task, ``self.frames`` is its process's tree (one per :class:`~dataflow.Deployer`);
a composite's ``<scart:frames ros1="true"/>`` adds :class:`FrameServer` (the tree as the
task ``tf``, with ports other processes and ``scart tf`` follow) and joins the tree to
ROS's ``/tf`` and ``/tf_static`` (:mod:`dataflow.tf.ros`).

How it answers (:mod:`dataflow.tf.buffer` has the details): translations interpolate
linearly and rotations by slerp between the two nearest stamps, exactly as tf2 does;
a time outside what is kept raises :class:`ExtrapolationError` naming both frames, the
time and the span held, unless ``extrapolate=`` allows it; no path raises
:class:`ConnectivityError`; statics hold for all time; a second parent or a cycle is
refused when published (:class:`FrameTreeError`); NaN, or a rotation too far from a unit
quaternion, is refused (:class:`TransformValueError`; from ROS: counted, said once).
"""

from typing import TYPE_CHECKING

from .buffer import DEFAULT_CACHE, FrameBuffer, FrameInfo
from .transform import (ConnectivityError, ExtrapolationError, FrameTreeError, Transform, TransformError,
                        TransformValueError, UnknownFrameError)

if TYPE_CHECKING:
    from .server import FrameServer

__all__ = ["DEFAULT_CACHE", "ConnectivityError", "ExtrapolationError", "FrameBuffer", "FrameInfo", "FrameServer",
           "FrameTreeError", "Transform", "TransformError", "TransformValueError", "UnknownFrameError"]


def __getattr__(name: str) -> object:
    """:class:`FrameServer` is imported when asked for (it brings tasks, ports and the
    transports with it; the buffer alone needs none of them)."""
    if name == "FrameServer":
        from .server import FrameServer

        return FrameServer
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
