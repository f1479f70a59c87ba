"""One frame's history: its parent, and its transforms by stamp (tf2's ``TimeCache`` and
``StaticCache``), kept in two parallel lists.

``stamps`` holds integer nanoseconds, ascending; ``data[i]`` is the transform at
``stamps[i]`` and what the interpolation towards the next one needs besides the time:
``(tx, ty, tz, qx, qy, qz, qw, theta, d0, d1, inv_dt, *next)`` — the slerp's constants
(see :func:`~dataflow.tf._math.interval`), one over the nanoseconds to the next stamp,
and the next transform's seven values (the same float objects, shared) — made once when
the pair is made, so that a lookup between two stamps reads one tuple. A static frame
keeps one entry, valid for all time. The two lists are changed in place, never
replaced (a lookup's remembered path holds them). Not thread-safe: the
:class:`~dataflow.tf.buffer.FrameBuffer` holding it serialises every access.
"""

from __future__ import annotations

import math
from bisect import bisect_left

from ._math import interval

__all__ = ["DUPLICATE", "Frame", "OLD", "STORED", "Values"]

Values = tuple[float, ...]  # tx, ty, tz, qx, qy, qz, qw
Entry = tuple[float, ...]  # 18 floats: see the module docstring

STORED, DUPLICATE, OLD = "stored", "duplicate", "old"
_LAST = (0.0,) * 11  # what follows the newest entry's values: there is no next one


def _entry(values: Values, after: Values | None = None, dt_ns: int = 0) -> Entry:
    """``values`` with the interpolation constants towards ``after``, ``dt_ns`` later
    (none: the newest entry)."""
    if after is None:
        return (*values, *_LAST)
    _, _, _, qx0, qy0, qz0, qw0 = values
    _, _, _, qx1, qy1, qz1, qw1 = after
    return (*values, *interval((qx0, qy0, qz0, qw0), (qx1, qy1, qz1, qw1)), 1.0 / dt_ns, *after)


class Frame:
    """One frame of the tree: ``name``, its one ``parent``, whether it is ``static``,
    who published it last (``authority``), and its transforms (see the module docstring)."""

    __slots__ = ("authority", "data", "name", "parent", "received", "static", "stamps")

    def __init__(self, name: str, parent: str, static: bool, authority: str) -> None:
        self.name, self.parent, self.static, self.authority = name, parent, static, authority
        self.stamps: list[int] = []
        self.data: list[Entry] = []
        self.received = 0  #: transforms stored (not counting duplicates), for the rate

    def reset(self, static: bool) -> None:
        """Forget the history and become static or dynamic (a frame changing kind starts
        afresh, as in tf2 for ROS 2)."""
        self.static = static
        self.stamps.clear()
        self.data.clear()

    def insert(self, stamp: int, values: Values, keep_ns: int, max_kept: int) -> str:
        """Store ``values`` at ``stamp``: :data:`STORED`, :data:`DUPLICATE` (the same values
        at the same stamp: nothing changed) or :data:`OLD` (older than ``keep_ns`` before
        the newest: refused, as tf2's ``TF_OLD_DATA``). Another value at a stamp held
        replaces it. Then drops what is older than ``keep_ns`` before the newest, and the
        oldest beyond ``max_kept`` entries."""
        if self.static:
            if self.data and self.data[0][:7] == values:
                return DUPLICATE
            self.stamps[:], self.data[:] = [stamp], [_entry(values)]
            self.received += 1
            return STORED
        stamps, data = self.stamps, self.data
        if not stamps or stamp > stamps[-1]:
            if data:
                data[-1] = _entry(data[-1][:7], values, stamp - stamps[-1])
            stamps.append(stamp)
            data.append(_entry(values))
        else:
            if stamp + keep_ns < stamps[-1]:
                return OLD
            i = bisect_left(stamps, stamp)
            if stamps[i] == stamp:
                if data[i][:7] == values:
                    return DUPLICATE
                last = i + 1 == len(data)
                data[i] = _entry(values) if last else _entry(values, data[i + 1][:7], stamps[i + 1] - stamp)
            else:
                stamps.insert(i, stamp)
                data.insert(i, _entry(values, data[i][:7], stamps[i + 1] - stamp))
            if i > 0:
                data[i - 1] = _entry(data[i - 1][:7], values, stamp - stamps[i - 1])
        self.received += 1
        self._prune(keep_ns, max_kept)
        return STORED

    def _prune(self, keep_ns: int, max_kept: int) -> None:
        stamps = self.stamps
        cut = stamps[-1] - keep_ns
        drop = bisect_left(stamps, cut) if stamps[0] < cut else 0
        drop = max(drop, len(stamps) - max_kept)
        if drop > 0:
            del stamps[:drop]
            del self.data[:drop]

    def at(self, t: int, extrapolate_ns: int) -> Values | None:
        """The transform at ``t`` (interpolated between the two nearest stamps; extrapolated
        from the nearest two, or held with one, up to ``extrapolate_ns`` beyond the span);
        None when ``t`` is outside what is kept (and the allowance)."""
        data = self.data
        if self.static:
            return data[0][:7]
        stamps = self.stamps
        i = bisect_left(stamps, t)
        n = len(stamps)
        if i < n and stamps[i] == t:
            return data[i][:7]
        if 0 < i < n:
            return _between(data[i - 1], (t - stamps[i - 1]) / (stamps[i] - stamps[i - 1]))
        beyond = t - stamps[-1] if i == n else stamps[0] - t
        if beyond > extrapolate_ns:
            return None
        if n == 1:
            return data[0][:7]
        j = n - 2 if i == n else 0
        return _between(data[j], (t - stamps[j]) / (stamps[j + 1] - stamps[j]))

    def span(self) -> tuple[int, int]:
        """The oldest and the newest stamp kept (0, 0 for a static frame)."""
        return (0, 0) if self.static or not self.stamps else (self.stamps[0], self.stamps[-1])


def _between(a: Entry, r: float) -> Values:
    """The transform at ratio ``r`` from entry ``a`` (0) to the next one (1): translation
    linear, rotation by slerp (tf2's ``TimeCache::interpolate``); ``r`` outside [0, 1]
    extrapolates."""
    x0, y0, z0, qx0, qy0, qz0, qw0, theta, d0, d1, _, x1, y1, z1, qx1, qy1, qz1, qw1 = a
    s = 1.0 - r
    if theta != 0.0:
        s0, s1 = math.sin(s * theta) * d0, math.sin(r * theta) * d1
        q = (qx0 * s0 + qx1 * s1, qy0 * s0 + qy1 * s1, qz0 * s0 + qz1 * s1, qw0 * s0 + qw1 * s1)
    else:
        q = (qx0, qy0, qz0, qw0)
    return (s * x0 + r * x1, s * y0 + r * y1, s * z0 + r * z1, *q)
