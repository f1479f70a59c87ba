"""One frame's history: its parent, and its transforms by stamp (tf2's ``TimeCache`` and
``StaticCache``), kept as flat arrays of numbers rather than an object per transform.

A dynamic frame keeps ``stamps`` (integer nanoseconds, ascending) and ``values``
(``array('d')``, :data:`WIDTH` numbers per stamp): the transform at the stamp,
then what the interpolation towards the next stamp needs besides the time, made once when
the pair is made::

    tx ty tz qx qy qz qw   vx vy vz   px py pz pw   w   lim

``v`` is the translation's change per nanosecond, ``p`` and ``w`` the slerp's other
quaternion and angle per nanosecond (:func:`~dataflow.tf._math.arc`), so the transform
``u`` ns after the stamp is ``(t + u v, cos(u w) q + sin(u w) p)`` — tf2's lerp and slerp,
rewritten so that a lookup reads one entry, at one offset, and takes one angle. ``lim``
is the nanoseconds to the next stamp, and half of one for the newest entry: ``u`` from
``lim`` on is another entry's (or, after the newest, outside the span). An entry is
128 bytes; with its stamp's place in the list (the int itself is shared by a message's
transforms), a transform kept takes about 140 (an object per transform took 454).

Entries before ``head`` are dropped: older than the cache time, or beyond the count kept.
They are removed from the arrays only once they are a sixteenth of them, so that a new
transform does not move the whole history each time. A static frame keeps its one
transform as ``fixed`` (seven floats) and its stamp, valid for all time. The arrays are
changed in place, never replaced (a lookup's remembered path holds them). Not
thread-safe: the :class:`~dataflow.tf.buffer.FrameBuffer` holding it serialises every
access.
"""

from __future__ import annotations

import math
import struct
from array import array
from bisect import bisect_left, bisect_right

from ._math import arc

__all__ = ["DUPLICATE", "ENTRY", "Frame", "OLD", "STORED", "TRANSFORM", "Values", "WIDTH"]

Values = tuple[float, ...]  # tx, ty, tz, qx, qy, qz, qw

WIDTH = 16  #: numbers per entry (see the module docstring)
ENTRY = struct.Struct(f"{WIDTH}d")  #: one entry, read at once: ``ENTRY.unpack_from(values, i * ENTRY.size)``
TRANSFORM = struct.Struct("7d")  #: an entry's transform alone, read the same way
_NEWEST = (0.0,) * (WIDTH - 8) + (0.5,)  # what follows the newest entry's transform: no next one

STORED, DUPLICATE, OLD = "stored", "duplicate", "old"


def _toward(values: Values, after: Values, dt_ns: int) -> tuple[float, ...]:
    """The interpolation constants from ``values`` to ``after``, ``dt_ns`` later."""
    x0, y0, z0, qx0, qy0, qz0, qw0 = values
    x1, y1, z1, qx1, qy1, qz1, qw1 = after
    theta, p = arc((qx0, qy0, qz0, qw0), (qx1, qy1, qz1, qw1))
    return (x1 - x0) / dt_ns, (y1 - y0) / dt_ns, (z1 - z0) / dt_ns, *p, theta / dt_ns, float(dt_ns)


class Frame:
    """One frame of the tree: ``name``, its one ``parent``, whether it is ``static``,
    who published it last (``authority``), and its transforms (see the module docstring)."""

    __slots__ = ("authority", "fixed", "fixed_stamp", "head", "name", "parent", "received", "static", "stamps",
                 "values")

    def __init__(self, name: str, parent: str, static: bool, authority: str) -> None:
        self.name, self.parent, self.static, self.authority = name, parent, static, authority
        self.stamps: list[int] = []
        self.values = array("d")
        self.head = 0  #: the first entry kept
        self.fixed: Values = ()  #: a static frame's transform (none yet: empty)
        self.fixed_stamp = 0
        self.received = 0  #: transforms stored (not counting duplicates), for the rate

    def reset(self, static: bool) -> None:
        """Forget the history and become static or dynamic (a frame changing kind starts
        afresh, as in tf2 for ROS 2)."""
        self.static = static
        del self.stamps[:]
        del self.values[:]
        self.head = 0
        self.fixed = ()

    def kept(self) -> int:
        """How many transforms the frame keeps."""
        return 1 if self.static else len(self.stamps) - self.head

    def transform(self, i: int) -> Values:
        """The transform of entry ``i``."""
        return TRANSFORM.unpack_from(self.values, i * ENTRY.size)

    def insert(self, stamp: int, values: Values, keep_ns: int, max_kept: int) -> str:
        """Store ``values`` at ``stamp``: :data:`STORED`, :data:`DUPLICATE` (the same values
        at the same stamp: nothing changed) or :data:`OLD` (older than ``keep_ns`` before
        the newest: refused, as tf2's ``TF_OLD_DATA``). Another value at a stamp held
        replaces it. Then drops what is older than ``keep_ns`` before the newest, and the
        oldest beyond ``max_kept`` entries."""
        if self.static:
            if self.fixed == values:
                return DUPLICATE
            self.fixed, self.fixed_stamp = values, stamp
            self.received += 1
            return STORED
        stamps = self.stamps
        n = len(stamps)
        if not n or stamp > stamps[-1]:  # the newest: the hot case
            if n:  # the entry before, newest until now, gets its constants towards this one
                last = self.transform(n - 1)
                del self.values[7 - WIDTH:]
                self.values.extend(_toward(last, values, stamp - stamps[-1]) + values + _NEWEST)
            else:
                self.values.extend(values + _NEWEST)
            stamps.append(stamp)
        else:
            if stamp + keep_ns < stamps[-1]:
                return OLD
            i = bisect_left(stamps, stamp, self.head)
            if stamps[i] == stamp:
                if self.transform(i) == values:
                    return DUPLICATE
                self.values[i * WIDTH:i * WIDTH + 7] = array("d", values)
            else:
                stamps.insert(i, stamp)
                self.values[i * WIDTH:i * WIDTH] = array("d", values + _NEWEST)
            self._relink(i)
            if i > self.head:
                self._relink(i - 1)
        self.received += 1
        self._prune(keep_ns, max_kept)
        return STORED

    def _relink(self, i: int) -> None:
        """Remake entry ``i``'s interpolation constants (towards entry ``i + 1``, if any)."""
        stamps = self.stamps
        after = _toward(self.transform(i), self.transform(i + 1), stamps[i + 1] - stamps[i]) \
            if i + 1 < len(stamps) else _NEWEST
        self.values[i * WIDTH + 7:(i + 1) * WIDTH] = array("d", after)

    def _prune(self, keep_ns: int, max_kept: int) -> None:
        stamps, head = self.stamps, self.head
        n = len(stamps)
        cut = stamps[-1] - keep_ns
        if stamps[head] < cut:
            head = bisect_left(stamps, cut, head)
        head = max(head, n - max_kept)
        if head * 16 >= n:  # a sixteenth of the arrays is dropped entries: remove them
            del stamps[:head]
            del self.values[:head * WIDTH]
            head = 0
        self.head = head

    def at(self, t: int, extrapolate_ns: int) -> Values | None:
        """The transform at ``t`` (interpolated between the two nearest stamps; extrapolated
        from the nearest two, or held with one, up to ``extrapolate_ns`` beyond the span);
        None when ``t`` is outside what is kept (and the allowance)."""
        if self.static:
            return self.fixed
        stamps, head = self.stamps, self.head
        n = len(stamps)
        i = bisect_right(stamps, t, head) - 1
        if i >= head and (i + 1 < n or t == stamps[i]):
            return self._interpolated(i, t - stamps[i])
        beyond = t - stamps[-1] if i >= head else stamps[head] - t
        if beyond > extrapolate_ns:
            return None
        if n - head == 1:
            return self.transform(head)
        j = n - 2 if i >= head else head
        return self._interpolated(j, t - stamps[j])

    def _interpolated(self, i: int, u: int) -> Values:
        """The transform ``u`` ns after entry ``i`` (before it when negative; beyond the
        next stamp extrapolates): translation linear, rotation by slerp."""
        x, y, z, qx, qy, qz, qw, vx, vy, vz, px, py, pz, pw, w, _ = ENTRY.unpack_from(self.values, i * ENTRY.size)
        c, s = math.cos(u * w), math.sin(u * w)
        return (x + u * vx, y + u * vy, z + u * vz, c * qx + s * px, c * qy + s * py, c * qz + s * pz,
                c * qw + s * pw)

    def span(self) -> tuple[int, int]:
        """The oldest and the newest stamp kept (0, 0 for a static frame)."""
        return (0, 0) if self.static or not self.stamps else (self.stamps[self.head], self.stamps[-1])
