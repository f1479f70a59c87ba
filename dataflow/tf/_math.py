"""Rigid-transform arithmetic on plain floats: quaternions ``(x, y, z, w)`` as ROS orders them.

Plain floats measure faster than numpy for one 3-vector or one quaternion at a time
(numpy's per-call overhead is larger than the arithmetic). :func:`slerp` is tf2's
``Quaternion::slerp`` step for step (half the shortest-path angle from ``acos``, the far
side taken when the dot product is negative, the first quaternion kept when the angle
is zero); the buffer interpolates with :func:`arc`, the same function rewritten, so its
rotations agree with tf2's to the rounding (~1e-16).
"""

from __future__ import annotations

import math

__all__ = ["QUATERNION_TOLERANCE", "Quat", "Vec", "arc", "axis_angle", "compose", "conjugate", "invert",
           "multiply", "rotate", "rpy", "from_rpy", "slerp"]

Vec = tuple[float, float, float]
Quat = tuple[float, float, float, float]

#: tf2's ``QUATERNION_NORMALIZATION_TOLERANCE``: a rotation whose squared norm is further
#: than this from 1 is refused (tf2's ``TF_DENORMALIZED_QUATERNION``).
QUATERNION_TOLERANCE = 10e-3


def multiply(a: Quat, b: Quat) -> Quat:
    """The Hamilton product ``a * b`` (first ``b``, then ``a``)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def conjugate(q: Quat) -> Quat:
    """The inverse rotation of a unit quaternion."""
    return (-q[0], -q[1], -q[2], q[3])


def rotate(q: Quat, v: Vec) -> Vec:
    """``v`` rotated by the unit quaternion ``q`` (``q v q*``, without building quaternions)."""
    qx, qy, qz, qw = q
    vx, vy, vz = v
    cx, cy, cz = 2.0 * (qy * vz - qz * vy), 2.0 * (qz * vx - qx * vz), 2.0 * (qx * vy - qy * vx)
    return (vx + qw * cx + qy * cz - qz * cy, vy + qw * cy + qz * cx - qx * cz, vz + qw * cz + qx * cy - qy * cx)


def compose(t1: Vec, q1: Quat, t2: Vec, q2: Quat) -> tuple[Vec, Quat]:
    """``(t1, q1) * (t2, q2)``: the second transform expressed through the first."""
    x, y, z = rotate(q1, t2)
    return (x + t1[0], y + t1[1], z + t1[2]), multiply(q1, q2)


def invert(t: Vec, q: Quat) -> tuple[Vec, Quat]:
    """The inverse of the rigid transform ``(t, q)``."""
    qi = conjugate(q)
    x, y, z = rotate(qi, t)
    return (-x, -y, -z), qi


def _half_angle(q0: Quat, q1: Quat) -> tuple[float, float, float]:
    """tf2's half angle between two rotations (``acos`` of their dot product over their
    norms, the shortest way), its cosine, and the dot product (negative: ``q1`` is taken
    negated)."""
    x0, y0, z0, w0 = q0
    x1, y1, z1, w1 = q1
    dot = x0 * x1 + y0 * y1 + z0 * z1 + w0 * w1
    norms = math.sqrt((x0 * x0 + y0 * y0 + z0 * z0 + w0 * w0) * (x1 * x1 + y1 * y1 + z1 * z1 + w1 * w1))
    cos = min(1.0, abs(dot) / norms)
    return math.acos(cos), cos, dot


def arc(q0: Quat, q1: Quat) -> tuple[float, Quat]:
    """What slerp from ``q0`` towards ``q1`` needs besides the ratio, computed once per pair
    of stamps: tf2's half angle ``theta`` and the unit quaternion ``p`` orthogonal to ``q0``
    in the plane of the two (``q1`` taken the short way). Then ``cos(r theta) q0 + sin(r
    theta) p`` is :func:`slerp`'s ``(sin((1 - r) theta) q0 + sin(r theta) q1) / sin(theta)``
    rewritten (the same function of ``theta``, to the rounding), with one angle to take per
    lookup instead of two. A zero angle gives ``(0, (0, 0, 0, 0))``: ``q0`` is kept, as tf2's."""
    theta, cos, dot = _half_angle(q0, q1)
    if theta == 0.0:
        return 0.0, (0.0, 0.0, 0.0, 0.0)
    sin = math.sin(theta)
    d, c = (-1.0 if dot < 0 else 1.0) / sin, cos / sin
    return theta, (q1[0] * d - q0[0] * c, q1[1] * d - q0[1] * c, q1[2] * d - q0[2] * c, q1[3] * d - q0[3] * c)


def slerp(q0: Quat, q1: Quat, ratio: float) -> Quat:
    """Spherical linear interpolation from ``q0`` (ratio 0) to ``q1`` (ratio 1), as tf2's
    ``Quaternion::slerp``, step for step (what the buffer's :func:`arc` form is tested against)."""
    theta, _, dot = _half_angle(q0, q1)
    if theta == 0.0:
        return q0
    d = 1.0 / math.sin(theta)
    s0, s1 = math.sin((1.0 - ratio) * theta) * d, math.sin(ratio * theta) * (-d if dot < 0 else d)
    return (q0[0] * s0 + q1[0] * s1, q0[1] * s0 + q1[1] * s1, q0[2] * s0 + q1[2] * s1, q0[3] * s0 + q1[3] * s1)


def axis_angle(axis: Vec, angle: float) -> Quat:
    """The rotation of ``angle`` rad about the unit vector ``axis``."""
    s = math.sin(angle / 2.0)
    return (axis[0] * s, axis[1] * s, axis[2] * s, math.cos(angle / 2.0))


def from_rpy(roll: float, pitch: float, yaw: float) -> Quat:
    """The rotation of fixed-axis roll (x), pitch (y) then yaw (z), as URDF and tf2's ``setRPY``."""
    cr, sr = math.cos(roll / 2.0), math.sin(roll / 2.0)
    cp, sp = math.cos(pitch / 2.0), math.sin(pitch / 2.0)
    cy, sy = math.cos(yaw / 2.0), math.sin(yaw / 2.0)
    return (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy)


def rpy(q: Quat) -> Vec:
    """Roll, pitch and yaw (rad) of a unit quaternion: the inverse of :func:`from_rpy`."""
    x, y, z, w = q
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw
