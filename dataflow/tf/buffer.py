"""The frame buffer: a transform tree with a history, looked up in time (tf2's ``BufferCore``).

Each frame has **one parent**, fixed when it is first published; a transform giving it
another, or closing a cycle, is refused when it is published (tf2 accepts both and fails
in a later lookup). A dynamic frame keeps its transforms of the last ``cache_time``
seconds before its newest (10 s by default, as tf2); a static one holds for all time.

:meth:`FrameBuffer.lookup` walks from each frame up to their common ancestor, as tf2
does, and composes the chain: between two stamps a translation is interpolated
linearly and a rotation by slerp, tf2's ``TimeCache`` formulas (the slerp rewritten with
one angle), so the two agree to the rounding (1e-15). Time 0 means the newest time every frame on the path has
(tf2's latest common time). A time outside what a frame keeps raises
:class:`~dataflow.tf.ExtrapolationError` naming both frames, the time asked and the
span held, unless ``extrapolate`` allows that many seconds beyond it. Two frames with
no path between them raise :class:`~dataflow.tf.ConnectivityError`.

Transforms come from :meth:`~FrameBuffer.publish` (code of this process: a bad one
raises) and :meth:`~FrameBuffer.receive` (from outside, as ROS's ``/tf``: a bad one is
refused, counted in :attr:`~FrameBuffer.refused` and logged once per reason). A
rotation whose squared norm is within tf2's tolerance of 1 is normalised; beyond it,
or with a number that is not finite, the transform is refused. The same values at a
stamp already held change nothing and are not passed on: what this process sends to
ROS and gets back stops there.

Thread-safe: one lock guards the tree; lookups hold it only while they compose.
Listeners (:meth:`~FrameBuffer.on_publish`) are called after it is released, in the
thread that published.
"""

from __future__ import annotations

import logging
import math
import re
import threading
import time
from array import array
from bisect import bisect_right
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import overload

from ._cache import DUPLICATE, ENTRY, OLD, TRANSFORM, Frame, Values
from ._math import QUATERNION_TOLERANCE
from .transform import (ConnectivityError, ExtrapolationError, FrameTreeError, Transform, TransformError,
                        TransformValueError, UnknownFrameError, seconds)

__all__ = ["DEFAULT_CACHE", "FrameBuffer", "FrameInfo", "Listener", "MAX_CACHE", "MAX_FRAMES", "MAX_KEPT"]

log = logging.getLogger(__name__)

DEFAULT_CACHE = 10.0  #: s of history a dynamic frame keeps (tf2's default)
MAX_CACHE = 3600.0  #: s, at most
MAX_FRAMES = 10_000  #: frames in one tree, at most
MAX_KEPT = 100_000  #: transforms one frame keeps, at most (1 kHz for 100 s)
MAX_NAME = 256  #: characters of a frame name, at most
_NAME = re.compile(r"[^\s/][^\s]{0,255}")
_PATHS = 4096  #: (target, source) pairs whose path is remembered, at most

#: ``listener(transforms, static, origin)``: what was stored, in the publisher's thread.
Listener = Callable[[list[Transform], bool, str], None]


@dataclass(frozen=True)
class FrameInfo:
    """One frame as :meth:`FrameBuffer.frames` shows it (``view_frames``' boxes): its
    parent, whether static, who published it last, how many transforms it keeps and
    their span (ns; 0 when static), the rate over that span (Hz) and how many it got."""

    name: str
    parent: str
    static: bool
    authority: str
    kept: int
    oldest_ns: int
    newest_ns: int
    rate: float
    received: int


Link = tuple["list[int] | None", "array[float]", Frame]


class _Path:
    """The frames from the source, and from the target, up to their common ancestor
    (excluded), each as ``(stamps, values, frame)`` (``stamps`` None for a static frame:
    what :func:`_walk` reads), and the stamps of the dynamic ones among them (for the
    latest common time). Remembered until the tree changes shape or a frame changes kind."""

    __slots__ = ("dynamic", "source", "source_name", "target", "target_name")

    def __init__(self, target_name: str, source_name: str, source: list[Frame], target: list[Frame]) -> None:
        self.target_name, self.source_name = target_name, source_name
        self.source: list[Link] = [(None if f.static else f.stamps, f.values, f) for f in source]
        self.target: list[Link] = [(None if f.static else f.stamps, f.values, f) for f in target]
        self.dynamic = [f.stamps for f in (*source, *target) if not f.static]


class _Miss(Exception):
    """A frame of the path has nothing at the time asked (turned into ExtrapolationError)."""

    def __init__(self, frame: Frame) -> None:
        super().__init__(frame.name)
        self.frame = frame


def _seconds(value: object) -> float:
    """A time argument as float seconds (an int too); raises ``TypeError`` for anything else."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeError(f"time {value!r:.40}: seconds, a number")
    return float(value)


def _ns(time_s: float) -> int:
    if not math.isfinite(time_s):
        raise TransformValueError(f"time {time_s!r}: a finite number of seconds")
    return round(time_s * 1e9)


def _strip(name: object) -> str:
    if not isinstance(name, str):
        raise FrameTreeError(f"frame name {name!r}: a string", "bad name")
    return name[1:] if name.startswith("/") else name


class FrameBuffer:
    """A transform tree with ``cache_time`` seconds of history per dynamic frame (see the
    module docstring). ``max_frames``, ``max_kept``: bounds on frames and on transforms
    kept per frame (the oldest go first)."""

    def __init__(self, cache_time: float = DEFAULT_CACHE, *, max_frames: int = MAX_FRAMES,
                 max_kept: int = MAX_KEPT) -> None:
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._waiting = 0
        self._frames: dict[str, Frame] = {}
        self._roots: set[str] = set()  # names known only as parents
        self._paths: dict[tuple[str, str], _Path] = {}
        self._listeners: tuple[tuple[Listener, str], ...] = ()
        self._refused: dict[str, int] = {}
        self._said: set[str] = set()
        self._stamp = 0  # the stamp stored last: the next transforms at the same time keep this one int
        self.max_frames, self.max_kept = max_frames, max_kept
        self.cache_time = cache_time

    # ---- settings ----------------------------------------------------------------------
    @property
    def cache_time(self) -> float:
        """Seconds of history a dynamic frame keeps before its newest transform."""
        return self._keep_ns / 1e9

    @cache_time.setter
    def cache_time(self, value: float) -> None:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value <= MAX_CACHE:
            raise ValueError(f"cache_time {value!r}: seconds, more than 0, at most {MAX_CACHE:g}")
        self._keep_ns = round(value * 1e9)

    # ---- adding transforms -------------------------------------------------------------
    def publish(self, transforms: Transform | Iterable[Transform], *, static: bool = False,
                authority: str = "") -> int:
        """Add ``transforms`` to the tree (static ones hold for all time) and pass them to
        the listeners (the process's ROS publishers among them); returns how many were
        stored (a duplicate or one too old for the cache is not: counted). Raises
        :class:`TransformValueError` or :class:`FrameTreeError` at the first that is
        refused (those before it are kept)."""
        batch = [transforms] if isinstance(transforms, Transform) else list(transforms)
        return self._add(batch, static, authority, "", strict=True)

    def receive(self, transforms: Iterable[Transform], *, static: bool = False, authority: str = "",
                origin: str = "") -> int:
        """Add transforms from outside this process (``origin``: e.g. ``"ros1"``); never
        raises for one: a refused transform is counted in :attr:`refused` and logged
        once per reason. Returns how many were stored. Listeners registered with the
        same ``origin`` are not given them back."""
        return self._add(list(transforms), static, authority, origin, strict=False)

    def _add(self, batch: list[Transform], static: bool, authority: str, origin: str, strict: bool) -> int:
        stored: list[Transform] = []
        error: TransformError | None = None
        with self._lock:
            for transform in batch:
                try:
                    parent, child, values = _checked(transform, self._frames)
                    if self._insert(parent, child, transform.stamp_ns, values, static, authority):
                        stored.append(transform)
                except TransformError as exc:
                    self._refuse(exc)
                    if strict:
                        error = exc
                        break
            if stored and self._waiting:
                self._changed.notify_all()
        if stored:
            for listener, own in self._listeners:
                if not origin or own != origin:
                    _call(listener, stored, static, origin)
        if error is not None:
            raise error
        return len(stored)

    def _insert(self, parent: str, child: str, stamp: int, values: Values, static: bool, authority: str) -> bool:
        frame = self._frames.get(child)
        if frame is None:
            frame = self._new_frame(parent, child, static, authority)
        elif frame.parent != parent:
            raise FrameTreeError(f"frame {child!r} has the parent {frame.parent!r}: a transform giving it the "
                                 f"parent {parent!r} is refused (one parent per frame)", "second parent")
        if frame.static != static:
            frame.reset(static)
            self._paths.clear()
        if stamp == self._stamp:  # a message's transforms share their stamp: so do the frames' histories
            stamp = self._stamp
        else:
            self._stamp = stamp
        outcome = frame.insert(stamp, values, self._keep_ns, self.max_kept)
        if outcome == OLD:
            self._refuse(TransformError(f"frame {child!r} at {seconds(stamp)} s: older than the "
                                        f"{self.cache_time:g} s kept before its newest, {seconds(frame.stamps[-1])}",
                                        "old"))
            return False
        if outcome == DUPLICATE:
            return False
        frame.authority = authority
        return True

    def _new_frame(self, parent: str, child: str, static: bool, authority: str) -> Frame:
        if len(self._frames) >= self.max_frames:
            raise FrameTreeError(f"frame {child!r}: the tree holds {self.max_frames} frames already", "full")
        ancestor: str | None = parent
        while ancestor is not None:
            if ancestor == child:
                raise FrameTreeError(f"frame {child!r} with the parent {parent!r} would close a cycle: "
                                     f"{child!r} is an ancestor of {parent!r}", "cycle")
            up = self._frames.get(ancestor)
            ancestor = up.parent if up is not None else None
        frame = Frame(child, parent, static, authority)
        self._frames[child] = frame
        self._roots.discard(child)
        if parent not in self._frames:
            self._roots.add(parent)
        self._paths.clear()
        return frame

    def _refuse(self, exc: TransformError) -> None:
        reason = exc.reason or "refused"
        self._refused[reason] = self._refused.get(reason, 0) + 1
        if reason not in self._said:
            self._said.add(reason)
            log.warning("frame tree: transform refused (%s): %s; such refusals are counted, this is said once",
                        reason, exc)

    @property
    def refused(self) -> dict[str, int]:
        """Transforms refused so far, by reason (``not finite``, ``not a unit quaternion``,
        ``second parent``, ``cycle``, ``bad name``, ``old``, ``full``); a copy."""
        with self._lock:
            return dict(self._refused)

    def on_publish(self, listener: Listener, origin: str = "") -> Callable[[], None]:
        """Call ``listener(transforms, static, origin)`` with what is stored from now on
        (not with what came from ``origin``, when given); returns the function that
        stops it (idempotent)."""
        entry = (listener, origin)
        with self._lock:
            self._listeners = (*self._listeners, entry)

        def stop() -> None:
            with self._lock:
                self._listeners = tuple(e for e in self._listeners if e is not entry)

        return stop

    # ---- lookups ------------------------------------------------------------------------
    @overload
    def lookup(self, target: str, source: str, time: float = 0.0, /, *, extrapolate: float = 0.0,
               timeout: float = 0.0, time_ns: int | None = None) -> Transform: ...  # noqa: E704

    @overload
    def lookup(self, target: str, target_time: float, source: str, source_time: float, fixed: str, /, *,
               extrapolate: float = 0.0, timeout: float = 0.0) -> Transform: ...

    def lookup(self, target: str, source: str | float, time: float | str = 0.0, /, *rest: float | str,
               extrapolate: float = 0.0, timeout: float = 0.0, time_ns: int | None = None) -> Transform:
        """The pose of ``source`` in ``target`` at ``time`` (s; 0: the newest time the whole
        path has), or ``time_ns`` (exact nanoseconds); tf2's ``lookupTransform``.

        The time-travel form ``lookup(target, target_time, source, source_time, fixed)``
        is where ``source`` was at ``source_time``, seen from ``target`` at
        ``target_time``, through ``fixed``, a frame taken as constant in time.

        ``extrapolate``: seconds a frame's history may be extended beyond its span (0:
        never). ``timeout``: seconds to wait for the transforms to arrive (0: answer now).
        Raises :class:`UnknownFrameError`, :class:`ConnectivityError`,
        :class:`ExtrapolationError` (after the timeout, the last of them)."""
        if not (rest or timeout or extrapolate) and time_ns is None and type(time) is float:
            # the hot case, written out: one time, no waiting, no extrapolation (what _lookup does)
            try:
                t = round(time * 1e9)
            except (ValueError, OverflowError):  # NaN, infinite
                t = _ns(time)
            self._lock.acquire()  # not `with`: half its cost, on every lookup
            try:
                path = self._paths.get((target, source))  # type: ignore[arg-type]  # a float source finds none
                if path is not None:
                    if t == 0 and path.dynamic:
                        t = min([stamps[-1] for stamps in path.dynamic])
                    try:
                        s = _walk(path.source, t, 0)
                        if s is not None and not path.target:  # the target is an ancestor of the source
                            return Transform(path.target_name, path.source_name, s[0], s[1], t)
                        g = _walk(path.target, t, 0) if path.target else None
                    except _Miss as miss:
                        raise self._extrapolation(path.target_name, path.source_name, t, 0, miss.frame) from None
                    return _combine(path.target_name, path.source_name, t, s, g)
            finally:
                self._lock.release()
        ext = _ns(extrapolate)
        if ext < 0:
            raise ValueError(f"extrapolate={extrapolate!r}: seconds, 0 or more")
        if len(rest) == 2:  # lookup(target, target_time, source, source_time, fixed)
            target_time, via, source_time, fixed = source, time, rest[0], rest[1]
            if not isinstance(via, str) or not isinstance(fixed, str):
                raise TypeError("lookup(target, target_time, source, source_time, fixed): the frames as str")
            tt, ts = _ns(_seconds(target_time)), _ns(_seconds(source_time))
            return self._waiting_for(timeout, lambda: self._travel(target, tt, via, ts, fixed, ext))
        if rest or not isinstance(source, str) or isinstance(time, str):
            raise TypeError("lookup(target, source, time=0.0) or lookup(target, target_time, source, source_time, "
                            "fixed), the frames as str and the times as float")
        t = time_ns if time_ns is not None else _ns(_seconds(time))
        return self._waiting_for(timeout, lambda: self._lookup(target, source, t, ext))

    def can_transform(self, target: str, source: str, time: float = 0.0, *, extrapolate: float = 0.0,
                      time_ns: int | None = None) -> bool:
        """Whether :meth:`lookup` would answer now."""
        try:
            self.lookup(target, source, time, extrapolate=extrapolate, time_ns=time_ns)
        except TransformError:
            return False
        return True

    def _waiting_for(self, timeout: float, attempt: Callable[[], Transform]) -> Transform:
        if not timeout > 0:
            return attempt()
        deadline = time.monotonic() + min(timeout, 3600.0)
        while True:
            try:
                return attempt()
            except TransformError:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise
                with self._lock:
                    self._waiting += 1
                    try:
                        self._changed.wait(min(left, 0.5))
                    finally:
                        self._waiting -= 1

    def _travel(self, target: str, tt: int, source: str, ts: int, fixed: str, ext: int) -> Transform:
        first = self._lookup(fixed, source, ts, ext)
        second = self._lookup(target, fixed, tt, ext)
        both = second * first
        return Transform(_strip(target), _strip(source), both.translation, both.rotation, second.stamp_ns)

    def _lookup(self, target: str, source: str, t: int, ext: int) -> Transform:
        with self._lock:
            path = self._paths.get((target, source))
            if path is None:
                if _strip(target) == _strip(source):
                    return self._identity(_strip(target), t)
                path = self._path(target, source, t)
            if t == 0 and path.dynamic:
                t = min([stamps[-1] for stamps in path.dynamic])
            try:
                s = _walk(path.source, t, ext)
                g = _walk(path.target, t, ext) if path.target else None
            except _Miss as miss:
                raise self._extrapolation(path.target_name, path.source_name, t, ext, miss.frame) from None
        return _combine(path.target_name, path.source_name, t, s, g)

    def _identity(self, frame: str, t: int) -> Transform:
        if frame not in self._frames and frame not in self._roots:
            raise UnknownFrameError(f"no frame {frame!r} in the tree; frames: {self._names_text()}")
        if t == 0:
            known = self._frames.get(frame)
            t = known.span()[1] if known is not None else 0
        return Transform(frame, frame, stamp_ns=t)

    def _path(self, asked_target: str, asked_source: str, t: int) -> _Path:
        """The path between two frames (remembered under the names asked, until the tree
        changes); raises :class:`UnknownFrameError`, :class:`ConnectivityError`."""
        target, source = _strip(asked_target), _strip(asked_source)
        for name in (target, source):
            if name not in self._frames and name not in self._roots:
                raise UnknownFrameError(f"cannot look up {source!r} in {target!r} at {seconds(t)} s: no frame "
                                        f"{name!r} in the tree; frames: {self._names_text()}")
        up_source, up_target = self._up(source), self._up(target)
        common = next((n for n in up_source if n in set(up_target)), None)
        if common is None:
            raise ConnectivityError(f"cannot look up {source!r} in {target!r} at {seconds(t)} s: no path joins "
                                    f"them ({source!r} is in the tree of {up_source[-1]!r}, {target!r} in the tree "
                                    f"of {up_target[-1]!r}); frames: {self._names_text()}")
        path = _Path(target, source, [self._frames[n] for n in up_source[:up_source.index(common)]],
                     [self._frames[n] for n in up_target[:up_target.index(common)]])
        if len(self._paths) >= _PATHS:
            self._paths.clear()
        self._paths[(asked_target, asked_source)] = path
        return path

    def _up(self, name: str) -> list[str]:
        """``name`` and its ancestors, up to the root."""
        out = [name]
        frame = self._frames.get(name)
        while frame is not None:
            out.append(frame.parent)
            frame = self._frames.get(frame.parent)
        return out

    def _extrapolation(self, target: str, source: str, t: int, ext: int, frame: Frame) -> ExtrapolationError:
        first, last = frame.span()
        held = (f"{frame.name!r} (child of {frame.parent!r}) is known at {seconds(first)} s only" if first == last
                else f"{frame.name!r} (child of {frame.parent!r}) is kept from {seconds(first)} to {seconds(last)} s")
        where = (f"{seconds(t - last)} s after its newest transform" if t > last
                 else f"{seconds(first - t)} s before its oldest (the buffer keeps {self.cache_time:g} s)")
        allowed = f"more than the {seconds(ext)} s of extrapolation allowed" if ext else "extrapolation not asked for"
        return ExtrapolationError(f"cannot look up {source!r} in {target!r} at {seconds(t)} s: {held}; the time "
                                  f"asked is {where} ({allowed})")

    # ---- what it holds ----------------------------------------------------------------
    def frames(self) -> list[FrameInfo]:
        """Every frame with a parent, by name (a snapshot)."""
        with self._lock:
            out = []
            for name in sorted(self._frames):
                f = self._frames[name]
                oldest, newest = f.span()
                kept = f.kept()
                rate = (kept - 1) / ((newest - oldest) / 1e9) if newest > oldest else 0.0
                out.append(FrameInfo(name, f.parent, f.static, f.authority, kept, oldest, newest, rate, f.received))
            return out

    def roots(self) -> list[str]:
        """The frames that are nobody's child (the roots of the trees held)."""
        with self._lock:
            return sorted(self._roots)

    def statics(self, excluding: str = "") -> list[Transform]:
        """Every static transform held (but those last published by ``excluding``, when given)."""
        with self._lock:
            return [Transform(f.parent, f.name, f.fixed[:3], f.fixed[3:], f.fixed_stamp)  # type: ignore[arg-type]  # 3 and 4 floats
                    for f in self._frames.values() if f.static and f.fixed and not (excluding and
                                                                                    f.authority == excluding)]

    def _names_text(self, limit: int = 20) -> str:
        names = sorted({*self._frames, *self._roots})
        more = f" and {len(names) - limit} more" if len(names) > limit else ""
        return (", ".join(names[:limit]) + more) or "none"

    def clear(self) -> None:
        """Forget every frame (tf2's ``clear``)."""
        with self._lock:
            self._frames.clear()
            self._roots.clear()
            self._paths.clear()


def _checked(transform: Transform, known: dict[str, Frame]) -> tuple[str, str, Values]:
    """Names (a leading ``/`` dropped, as tf2) and values of ``transform``, a rotation
    further than 1e-12 from unit normalised; raises :class:`FrameTreeError` or
    :class:`TransformValueError`. A name ``known`` was checked when its frame was made."""
    if type(transform) is not Transform and not isinstance(transform, Transform):
        raise TransformValueError(f"{transform!r:.80}: a dataflow.tf.Transform", "not numbers")
    parent, child = transform.frame_id, transform.child_frame_id
    if child not in known or parent[:1] == "/" or child[:1] == "/":
        parent, child = _strip(parent), _strip(child)
        for what, name in (("frame_id", parent), ("child_frame_id", child)):
            if not _NAME.fullmatch(name):
                raise FrameTreeError(f"{what} {name[:80]!r}: a frame name (1 to {MAX_NAME} characters, no space, "
                                     "not only '/')", "bad name")
    if parent == child:
        raise FrameTreeError(f"frame {child!r} cannot be its own parent", "bad name")
    try:
        tx, ty, tz = map(float, transform.translation)
        qx, qy, qz, qw = map(float, transform.rotation)
    except (TypeError, ValueError):
        raise TransformValueError(f"frame {child!r}: translation (x, y, z) and rotation (x, y, z, w) are numbers, "
                                  f"not {transform.translation!r:.60} and {transform.rotation!r:.60}", "not numbers") from None
    if not math.isfinite(tx + ty + tz + qx + qy + qz + qw) and not all(  # the sum: one test when all is well
            map(math.isfinite, (tx, ty, tz, qx, qy, qz, qw))):
        raise TransformValueError(f"frame {child!r} (parent {parent!r}): a number is not finite: translation "
                                  f"{(tx, ty, tz)}, rotation {(qx, qy, qz, qw)}", "not finite")
    norm2 = qx * qx + qy * qy + qz * qz + qw * qw
    off = abs(norm2 - 1.0)
    if off >= QUATERNION_TOLERANCE:
        raise TransformValueError(f"frame {child!r} (parent {parent!r}): rotation {(qx, qy, qz, qw)} is not a unit "
                                  f"quaternion (squared norm {norm2:.6g}; tf2's tolerance {QUATERNION_TOLERANCE:g})",
                                  "not a unit quaternion")
    if off > 1e-12:
        n = math.sqrt(norm2)
        qx, qy, qz, qw = qx / n, qy / n, qz / n, qw / n
    return parent, child, (tx, ty, tz, qx, qy, qz, qw)


def _call(listener: Listener, stored: list[Transform], static: bool, origin: str) -> None:
    try:
        listener(stored, static, origin)
    except Exception:  # noqa: BLE001 - a listener's bug never stops a publisher
        log.exception("frame tree: a listener of published transforms failed")


Acc = tuple[tuple[float, float, float], tuple[float, float, float, float]]


def _walk(chain: list[Link], t: int, ext: int, bisect: Callable[..., int] = bisect_right,
          read: Callable[[array[float], int], tuple[float, ...]] = ENTRY.unpack_from,
          read7: Callable[[array[float], int], tuple[float, ...]] = TRANSFORM.unpack_from, size: int = ENTRY.size,
          sin: Callable[[float], float] = math.sin, cos: Callable[[float], float] = math.cos) -> Acc | None:
    """The transform from the first frame of ``chain`` up to the parent of its last, at
    ``t`` (None for an empty chain: the identity). The hot path of every lookup, written
    out in plain floats: per frame one bisection, one entry read at once, one angle (see
    :mod:`dataflow.tf._cache`), then the composition. Frames published together (a
    robot's joints, in one message) keep the same stamps: where the frame below found
    ``t``, at the same place in its history and at the same stamp, the next one's is too,
    without a bisection. Raises :class:`_Miss` for a frame with nothing at ``t``."""
    first = True
    ox = oy = oz = ax = ay = az = aw = 0.0
    at = -1  # where the frame below found t, counted from its oldest entry kept
    stamp = None  # the stamp there, and t's nanoseconds after it
    u = -1.0
    for stamps, values, frame in chain:
        if stamps is None:  # static
            x, y, z, qx, qy, qz, qw = frame.fixed
        else:
            h = frame.head
            i = at + h
            if not (h <= i < len(stamps) and stamps[i] == stamp):  # else: where the frame below found t
                i = bisect(stamps, t, h) - 1
                at = i - h
                if i >= h:
                    stamp = stamps[i]
                    u = float(t - stamp)
                else:
                    u = -1.0  # before the oldest stamp kept
            if u > 0.0:
                x, y, z, qx, qy, qz, qw, vx, vy, vz, px, py, pz, pw, w, lim = read(values, i * size)
                if u < lim:  # between two stamps: the hot case
                    a = u * w
                    c, s = cos(a), sin(a)
                    qx = c * qx + s * px  # one statement each: no tuple made and taken apart
                    qy = c * qy + s * py
                    qz = c * qz + s * pz
                    qw = c * qw + s * pw
                    x += u * vx
                    y += u * vy
                    z += u * vz
                else:  # after the newest stamp (or this frame's next stamp comes first)
                    x, y, z, qx, qy, qz, qw = _outside(frame, t, ext)
            elif u == 0.0:  # at a stamp (at the newest: time 0)
                x, y, z, qx, qy, qz, qw = read7(values, i * size)
            else:
                x, y, z, qx, qy, qz, qw = _outside(frame, t, ext)
        if first:
            ox, oy, oz, ax, ay, az, aw = x, y, z, qx, qy, qz, qw
            first = False
            continue
        # the parent's transform applied to what is accumulated: rotate and translate, then multiply
        cx, cy, cz = 2.0 * (qy * oz - qz * oy), 2.0 * (qz * ox - qx * oz), 2.0 * (qx * oy - qy * ox)
        ox, oy, oz = ox + qw * cx + qy * cz - qz * cy + x, oy + qw * cy + qz * cx - qx * cz + y, \
            oz + qw * cz + qx * cy - qy * cx + z
        bx = qw * ax + qx * aw + qy * az - qz * ay
        by = qw * ay - qx * az + qy * aw + qz * ax
        bz = qw * az + qx * ay - qy * ax + qz * aw
        aw = qw * aw - qx * ax - qy * ay - qz * az
        ax, ay, az = bx, by, bz
    return None if first else ((ox, oy, oz), (ax, ay, az, aw))


def _outside(frame: Frame, t: int, ext: int) -> Values:
    """A frame's transform at a time outside its span, or after a stamp the frame below
    does not have (as :meth:`Frame.at` says); raises :class:`_Miss` for none."""
    got = frame.at(t, ext)
    if got is None:
        raise _Miss(frame)
    return got


def _combine(target: str, source: str, t: int, s: Acc | None, g: Acc | None) -> Transform:
    """The source's chain composed with the inverse of the target's (tf2's ``finalize``)."""
    if g is None:
        return Transform(target, source, s[0], s[1], t) if s is not None else Transform(target, source, stamp_ns=t)
    (gx, gy, gz), (bx, by, bz, bw) = g
    bx, by, bz = -bx, -by, -bz  # the target's rotation inverted
    (vx, vy, vz), (ax, ay, az, aw) = s if s is not None else ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    vx, vy, vz = vx - gx, vy - gy, vz - gz
    cx, cy, cz = 2.0 * (by * vz - bz * vy), 2.0 * (bz * vx - bx * vz), 2.0 * (bx * vy - by * vx)
    return Transform(target, source,
                     (vx + bw * cx + by * cz - bz * cy, vy + bw * cy + bz * cx - bx * cz, vz + bw * cz + bx * cy - by * cx),
                     (bw * ax + bx * aw + by * az - bz * ay, bw * ay - bx * az + by * aw + bz * ax,
                      bw * az + bx * ay - by * ax + bz * aw, bw * aw - bx * ax - by * ay - bz * az), t)
