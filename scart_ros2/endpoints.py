"""Publishers, subscriptions and the one thread that delivers a participant's samples.

A :class:`Publisher` converts and writes on the caller's thread. A :class:`Subscription`
is fed by its participant's :class:`Dispatcher`: one owned thread waits on a Cyclone DDS
waitset over every reader of the participant (RTT's mqueue dispatcher), takes each
sample, converts it and calls the subscription's callback on that thread.

A sample that cannot be converted (out of range for the type, wrong shape, malformed
CDR, refused by the ``accept`` hook) is refused and counted, never raised at the peer
or the callback. ``publish`` returns whether the sample was handed to DDS.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from cyclonedds.core import DDSException, GuardCondition, InstanceState, ReadCondition, SampleState, ViewState, WaitSet
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.util import duration
from cyclonedds._clayer import ddspy_take, ddspy_write  # type: ignore[import-not-found]  # its C layer ships no stub

from .errors import ConversionError
from .network import delete_entity

__all__ = ["Publisher", "Subscription", "PublisherStats", "SubscriptionStats", "Dispatcher", "write_cdr"]

LOG = logging.getLogger("scart_ros2")
_BATCH = 256  # samples one reader may deliver per wake before the others get their turn
_ANY = SampleState.Any | ViewState.Any | InstanceState.Any
Accept = Callable[[Any], bool]


@dataclass(frozen=True)
class PublisherStats:
    """What a publisher did: samples handed to DDS, samples refused (and the last reason)."""

    published: int
    refused: int
    last_refusal: str | None


@dataclass(frozen=True)
class SubscriptionStats:
    """What a subscription saw: valid samples taken, delivered to the callback, refused
    (malformed, unconvertible or refused by ``accept``), callbacks that raised."""

    received: int
    delivered: int
    refused: int
    callback_errors: int
    last_refusal: str | None


class Publisher:
    """Writes messages of one ROS 2 type to one topic (made by ``Participant.publisher``).

    ``publish`` is thread-safe and never blocks on readers (keep-last history).
    """

    def __init__(self, writer: DataWriter, convert: Callable[[object], object], topic: str, type_name: str,
                 accept: Accept | None, cdr: bool = False) -> None:
        self.topic, self.type_name = topic, type_name
        self._writer, self._convert, self._accept = writer, convert, accept
        self._write = (lambda data: write_cdr(writer, data)) if cdr else writer.write
        self._lock = threading.Lock()
        self._published = self._refused = 0
        self._last_refusal: str | None = None
        self._closed = False
        self.closed_hook: Callable[[], None] | None = None  # the participant's (node graph)

    def publish(self, message: object) -> bool:
        """Convert ``message`` (rosbags message, mapping or IDL instance) and write it.

        Returns True once handed to DDS; False if refused (counted in :meth:`stats`) or
        closed. Never raises for a bad sample.
        """
        if self._closed:
            return False
        try:
            if self._accept is not None and not self._accept(message):
                return self._refuse("refused by the accept hook")
            sample = self._convert(message)
            self._write(sample)
        except ConversionError as exc:
            return self._refuse(str(exc))
        except DDSException as exc:
            return False if self._closed else self._refuse(f"DDS refused the write: {exc}")
        except Exception as exc:  # cyclonedds' serialiser raises bare exceptions; the accept hook anything
            return self._refuse(f"{self.type_name}: {exc}")
        with self._lock:
            self._published += 1
        return True

    def _refuse(self, why: str) -> bool:
        with self._lock:
            self._refused += 1
            self._last_refusal = why
        return False

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called (``publish`` then returns False, refusing nothing)."""
        return self._closed

    def matched(self) -> int:
        """How many readers this publisher is matched with now (0 once closed)."""
        if self._closed:
            return 0
        try:
            return len(self._writer.get_matched_subscriptions())
        except DDSException:
            return 0

    def stats(self) -> PublisherStats:
        """The counts so far (thread-safe)."""
        with self._lock:
            return PublisherStats(self._published, self._refused, self._last_refusal)

    def close(self) -> None:
        """Delete the writer (readers see it leave). Idempotent; thread-safe."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        if self.closed_hook is not None:
            self.closed_hook()
        delete_entity(self._writer)


def write_cdr(writer: DataWriter, data: object) -> None:
    """Write CDR bytes (a buffer, its length a multiple of 4) as one sample of
    ``writer``'s type, with no serialiser of Cyclone's Python side: the bytes-level call
    its ``DataWriter.write`` makes after serialising. Raises ``DDSException``."""
    ret = ddspy_write(writer._ref, data)
    if ret < 0:
        raise DDSException(ret, f"Occurred while writing sample in {writer!r}")


def _take_cdr(reader: DataReader) -> list[tuple[bytes, Any]]:  # (CDR, Cyclone's untyped sample info)
    """Take one sample of ``reader`` as its CDR bytes and sample info, with no
    deserialiser of Cyclone's Python side (the bytes-level call ``DataReader.take``
    makes). Raises ``DDSException``."""
    taken = ddspy_take(reader._ref, _ANY, 1)
    if isinstance(taken, int):
        raise DDSException(taken, f"Occurred while taking data in {reader!r}")
    return list(taken)


class Subscription:
    """Delivers the messages of one ROS 2 topic to ``callback`` on the participant's
    dispatcher thread (made by ``Participant.subscribe``). With ``cdr``, ``convert`` is
    given each sample's CDR bytes instead of Cyclone's deserialised instance."""

    def __init__(self, reader: DataReader, convert: Callable[[Any], Any], callback: Callable[[Any], Any],
                 topic: str, type_name: str, accept: Accept | None, dispatcher: Dispatcher, cdr: bool = False) -> None:
        self.topic, self.type_name = topic, type_name
        self._reader, self._convert, self._callback, self._accept = reader, convert, callback, accept
        self._dispatcher = dispatcher
        self._condition = ReadCondition(reader, _ANY)
        self._take: Callable[[], list[tuple[Any, Any]]] = (  # (IDL instance or CDR, sample info)
            (lambda: _take_cdr(reader)) if cdr else
            (lambda: [(s, s.sample_info) for s in reader.take(N=1, condition=self._condition)]))
        self._received = self._delivered = self._refused = self._errors = 0
        self._last_refusal: str | None = None
        self._closed = False
        self.closed_hook: Callable[[], None] | None = None  # the participant's (node graph)
        #: Called with the reason each time a sample is refused (on the dispatcher thread).
        self.refused_hook: Callable[[str], None] | None = None
        dispatcher.add(self._condition, self._drain)

    def _drain(self) -> None:
        """Take and deliver up to a batch of samples (dispatcher thread only)."""
        for _ in range(_BATCH):
            if self._closed:
                return
            try:
                taken = self._take()
            except DDSException:
                return
            except Exception as exc:  # the sample could not be deserialised: it is gone, count it
                self._refuse(f"{self.type_name}: malformed sample: {exc}")
                continue
            if not taken:
                return
            sample, info = taken[0]
            if info.valid_data:
                self._received += 1
                self._deliver(sample)

    def _deliver(self, sample: object) -> None:
        try:
            message = self._convert(sample)
            if self._accept is not None and not self._accept(message):
                self._refuse("refused by the accept hook")
                return
        except Exception as exc:  # a ConversionError, or anything the accept hook raised
            self._refuse(str(exc) or type(exc).__name__)
            return
        try:
            self._callback(message)
            self._delivered += 1
        except Exception:
            self._errors += 1
            if self._errors == 1:
                LOG.exception("ROS 2 subscription %s: the callback raised (counted from now on)", self.topic)

    def _refuse(self, why: str) -> None:
        self._refused += 1
        self._last_refusal = why
        if self.refused_hook is not None:
            self.refused_hook(why)

    def matched(self) -> int:
        """How many writers this subscription is matched with now (0 once closed)."""
        if self._closed:
            return 0
        try:
            return len(self._reader.get_matched_publications())
        except DDSException:
            return 0

    def stats(self) -> SubscriptionStats:
        """The counts so far (written by the dispatcher thread; read from any)."""
        return SubscriptionStats(self._received, self._delivered, self._refused, self._errors,
                                 self._last_refusal)

    def close(self) -> None:
        """Stop delivering and delete the reader. Once it returns, the callback is not
        running and will not be called (unless close is called from the callback itself).
        Idempotent; thread-safe."""
        if self._closed:
            return
        self._closed = True
        self._dispatcher.retire(self._condition, self.closed_hook, self._reader)


class Dispatcher:
    """One owned thread waiting on a waitset over a participant's readers.

    Started by the first :meth:`add`, never in ``__init__``; :meth:`close` signals it (a
    guard condition wakes the wait), then joins it. Thread-safe.
    """

    def __init__(self, participant: DomainParticipant, name: str) -> None:
        self._name = name
        self._waitset = WaitSet(participant)
        self._guard = GuardCondition(participant)
        self._waitset.attach(self._guard)
        self._guard_set = False  # whether the guard may be triggered (resetting it is a ctypes call)
        self._drains: dict[int, tuple[object, Callable[[], None]]] = {}
        self._busy = threading.RLock()  # held while draining: remove() waits for a running drain
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def add(self, condition: ReadCondition | GuardCondition, drain: Callable[[], None]) -> None:
        """Call ``drain`` whenever ``condition`` triggers."""
        with self._lock:
            if self._stop.is_set():
                raise RuntimeError("the participant is closed")
            self._waitset.attach(condition)
            self._drains[id(condition)] = (condition, drain)
            if self._thread is None:
                self._thread = threading.Thread(target=self._main, name=self._name, daemon=True)
                self._thread.start()
        self._wake()  # look at the new reader now: it may already hold samples

    def remove(self, condition: ReadCondition | GuardCondition) -> None:
        """Stop calling the drain of ``condition``; waits for a drain in progress."""
        with self._busy, self._lock:
            if self._drains.pop(id(condition), None) is not None and not self._stop.is_set():
                self._waitset.detach(condition)

    def retire(self, condition: ReadCondition, closed_hook: Callable[[], None] | None, *entities: object) -> None:
        """An endpoint's close: stop calling ``condition``'s drain (waiting for one in
        progress), tell ``closed_hook``, then delete ``condition`` and ``entities``."""
        self.remove(condition)
        if closed_hook is not None:
            closed_hook()
        for entity in (condition, *entities):
            delete_entity(entity)

    def _wake(self) -> None:
        # trigger, then flag: the loop resets only a guard it knows may be set, so a guard
        # can never stay triggered unflagged (which would spin the wait)
        self._guard.set(True)
        self._guard_set = True

    def _main(self) -> None:
        try:
            self._run()
        except Exception:  # noqa: BLE001 - the participant's thread never dies silently
            LOG.exception("thread %s failed", self._name)

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self._waitset.wait(duration(seconds=1))
            except DDSException:
                return
            if self._guard_set:
                self._guard_set = False
                self._guard.set(False)
            with self._lock:
                drains = list(self._drains.values())
            with self._busy:
                for condition, drain in drains:
                    if self._stop.is_set():
                        return
                    if id(condition) in self._drains:  # an empty take costs less than asking triggered
                        drain()

    def close(self, timeout: float = 5.0) -> None:
        """Signal the thread, join it (not from itself), delete the waitset. Idempotent."""
        with self._lock:
            if self._stop.is_set():
                return
            self._stop.set()
        self._wake()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():  # (never from the thread itself)
            thread.join(timeout)
            if thread.is_alive():
                LOG.warning("thread %s did not end within %.1f s", self._name, timeout)
        if self._busy.acquire(timeout=timeout):  # a drain stuck in a callback: the participant's deletion frees these
            try:
                delete_entity(self._waitset)
                delete_entity(self._guard)
            finally:
                self._busy.release()
