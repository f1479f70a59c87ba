"""What a frame tree holds and answers: :class:`Transform`, and the errors of :mod:`dataflow.tf`."""

from __future__ import annotations

import math
from dataclasses import dataclass

from dataflow.errors import DataflowError

from ._math import Quat, Vec, compose, from_rpy, invert, rotate, rpy

__all__ = ["ConnectivityError", "ExtrapolationError", "FrameTreeError", "Transform", "TransformError",
           "TransformValueError", "UnknownFrameError", "seconds"]


class TransformError(DataflowError):
    """Base of what :mod:`dataflow.tf` raises; ``reason`` names a refusal's kind (``cycle``,
    ``not finite``...: how :attr:`FrameBuffer.refused <dataflow.tf.FrameBuffer.refused>`
    counts it)."""

    def __init__(self, message: str, reason: str = "") -> None:
        super().__init__(message)
        self.reason = reason


class UnknownFrameError(TransformError, LookupError):
    """A lookup names a frame the tree does not hold (tf2's ``LookupException``)."""


class ConnectivityError(TransformError):
    """No path joins the two frames of a lookup: they are in two trees (tf2's ``ConnectivityException``)."""


class ExtrapolationError(TransformError):
    """A lookup asks for a time outside what a frame on its path keeps (tf2's
    ``ExtrapolationException``); the message names both frames, the time and the span held."""


class FrameTreeError(TransformError, ValueError):
    """A transform that would break the tree, refused when it is published: a frame
    given a second parent, a cycle, a frame its own parent, or a bad frame name."""


class TransformValueError(TransformError, ValueError):
    """A transform with a number that is not finite, or a rotation too far from a unit quaternion."""


def seconds(stamp_ns: int) -> str:
    """A stamp as an error message shows it: seconds, to the nanosecond."""
    sign = "-" if stamp_ns < 0 else ""
    whole, ns = divmod(abs(stamp_ns), 1_000_000_000)
    return f"{sign}{whole}.{ns:09d}"


@dataclass(slots=True)
class Transform:
    """A stamped rigid transform: the pose of ``child_frame_id`` in ``frame_id`` (ROS's
    ``geometry_msgs/TransformStamped``), i.e. what maps points of the child frame into the
    parent frame.

    ``translation`` in metres, ``rotation`` a unit quaternion ``(x, y, z, w)``,
    ``stamp_ns`` the time in integer nanoseconds (ROS's ``sec``/``nsec``, exact;
    ``time.time_ns()`` for now), :attr:`stamp` the same in seconds. A value: nothing in
    :mod:`dataflow.tf` changes one once made, and neither should its users (it is not
    frozen only because a frozen dataclass takes four times as long to make, and every
    lookup makes one).
    """

    frame_id: str
    child_frame_id: str
    translation: Vec = (0.0, 0.0, 0.0)
    rotation: Quat = (0.0, 0.0, 0.0, 1.0)
    stamp_ns: int = 0

    @classmethod
    def from_rpy(cls, frame_id: str, child_frame_id: str, xyz: Vec = (0.0, 0.0, 0.0),
                 rpy: Vec = (0.0, 0.0, 0.0), stamp_ns: int = 0) -> Transform:
        """A transform from a translation and fixed-axis roll, pitch, yaw (rad), as URDF writes them."""
        return cls(frame_id, child_frame_id, (float(xyz[0]), float(xyz[1]), float(xyz[2])), from_rpy(*rpy), stamp_ns)

    @property
    def stamp(self) -> float:
        """The stamp in seconds (a float: beyond ~10^6 s it resolves less than a nanosecond)."""
        return self.stamp_ns / 1e9

    @property
    def rpy(self) -> Vec:
        """The rotation as roll, pitch, yaw (rad), as ``tf_echo`` prints it."""
        return rpy(self.rotation)

    def inverse(self) -> Transform:
        """The pose of ``frame_id`` in ``child_frame_id``."""
        t, q = invert(self.translation, self.rotation)
        return Transform(self.child_frame_id, self.frame_id, t, q, self.stamp_ns)

    def __mul__(self, other: Transform) -> Transform:
        """``a * b``: ``b`` (child of ``a``'s child) expressed in ``a.frame_id``; the stamp is ``a``'s."""
        if not isinstance(other, Transform):
            return NotImplemented
        t, q = compose(self.translation, self.rotation, other.translation, other.rotation)
        return Transform(self.frame_id, other.child_frame_id, t, q, self.stamp_ns)

    def apply(self, point: Vec) -> Vec:
        """``point`` (in ``child_frame_id``) expressed in ``frame_id``."""
        x, y, z = rotate(self.rotation, point)
        return x + self.translation[0], y + self.translation[1], z + self.translation[2]

    def is_finite(self) -> bool:
        """Whether every number is finite."""
        return all(math.isfinite(v) for v in (*self.translation, *self.rotation))
