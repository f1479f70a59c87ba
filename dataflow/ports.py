"""Input and output ports and the connections between them (RTT 2.9 semantics).

An :class:`OutputPort` fans out to any number of :class:`InputPort` s, each
connection with its own :class:`~dataflow.policy.ConnPolicy` and (by default) its own
storage; an input port may have several incoming connections. Hot path:

* ``out.write(v) -> WriteStatus``: ``NOT_CONNECTED`` without connections (the value is
  still kept as ``last_written_value()``), ``WRITE_FAILURE`` when at least one full
  ``BUFFER`` of a mandatory connection (the default) rejected the sample,
  ``WRITE_SUCCESS`` otherwise. A ``CIRCULAR_BUFFER``
  drops its oldest sample and succeeds. A value of the wrong type raises
  :class:`~dataflow.errors.PortTypeError` (a programming error, not a flow condition).
* ``inp.read() -> (FlowStatus, value)``: ``NO_DATA`` when nothing has arrived (or after
  ``clear()``), ``NEW_DATA`` for a sample not read before, ``OLD_DATA`` with the last
  sample when nothing new arrived. With several connections the port drains its current
  channel, then the others in connection order (the first with new data becomes current).

Truth table (one connection; RTT 2.9):

=====================================  =================  ======================  ==========
situation                              ``write`` returns  next ``read`` returns   ``dropped``
=====================================  =================  ======================  ==========
no connection                          NOT_CONNECTED      (NO_DATA, None)         —
connected, nothing written yet         —                  (NO_DATA, None)         —
DATA: written                          WRITE_SUCCESS      (NEW_DATA, v)           —
DATA: read already, nothing new        —                  (OLD_DATA, v)           —
DATA: written twice before a read      WRITE_SUCCESS      (NEW_DATA, v2)          +1
BUFFER(n) full                         WRITE_FAILURE      (NEW_DATA, oldest)      +1
CIRCULAR_BUFFER(n) full                WRITE_SUCCESS      (NEW_DATA, 2nd oldest)  +1
buffer drained                         —                  (OLD_DATA, last read)   —
after ``inp.clear()``                  —                  (NO_DATA, None)         —
=====================================  =================  ======================  ==========

Lock-free guarantee: with ``LockPolicy.LOCK_FREE`` (the default) no reader or writer ever
waits on a lock held by another port user — ``write``/``read`` take no lock at all; each
step is one operation CPython performs atomically under the GIL (a reference swap, a
``list.pop``, a ``deque.append``/``popleft``); :mod:`dataflow.buffers` details each
storage and what changes on free-threaded Python (per-object critical sections of a few
instructions replace the GIL). The sets of connections seen by the hot path are
immutable tuples replaced whole on connect/disconnect (copy-on-write), so a writer
iterating its connections never races a connect; connect/disconnect (the setup path)
serialise on one lock, which the hot path never takes. ``LOCKED`` connections take a
per-connection lock on every operation; ``UNSYNC`` ones are for single-threaded use.

``init`` (RTT 2.9 defaults): ``ConnPolicy.data()`` seeds a new connection with the
output's last written value, ``ConnPolicy()``, ``.buffer(n)``, ``.circular_buffer(n)``
do not (see :mod:`dataflow.policy`).

Ownership: a written sample is handed over by reference, not copied (RTT copies by value;
in Python a copy per write and per reader would cost more than the port itself). Once
written, a sample belongs to the readers: write a new object each cycle (as the youBot
driver does) or a frozen pydantic model, and never mutate a sample you wrote or read —
exactly the rule of ROS 2's zero-copy (loaned) messages. Samples that cross a process are
encoded when the server sends them, so mutating one after ``write`` can also change what
a remote subscriber receives.

Data callbacks (``inp.add_data_callback(cb)``) run ``cb(inp)`` in the writer's thread
after a sample was stored for that input; a rejected write fires nothing. A callback
that raises is logged and never disturbs the writer.
"""

from __future__ import annotations

import builtins
import dataclasses
import itertools
import logging
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Generic, TypeVar, overload

import pydantic

from scart_wire.bounds import Bounds, bounded_adapter
from .buffers import _NONE, DataObject, Storage, make_storage
from .errors import DataflowError, PortTypeError, PortValueError
from .policy import BufferPolicy, ConnPolicy, FlowStatus, WriteStatus
from scart_wire.types import registry

if TYPE_CHECKING:
    from .task import TaskContext
    from .transports.ends import Fanout
    from .transports.streams import PortStream

__all__ = ["InputPort", "OutputPort", "Connection", "ChannelConnection", "Port"]

log = logging.getLogger(__name__)
T = TypeVar("T")
#: Called with an input port after a sample was stored for it (its result is ignored).
DataCallback = Callable[["InputPort[T]"], object]

_setup_lock = threading.RLock()  # connect/disconnect only; never taken by read/write
_NO_DATA = (FlowStatus.NO_DATA, None)
_NEW = FlowStatus.NEW_DATA
_SUCCESS = WriteStatus.WRITE_SUCCESS
_FAILURE = WriteStatus.WRITE_FAILURE
_NOT_CONNECTED = WriteStatus.NOT_CONNECTED


class Connection(Generic[T]):
    """One output→input connection. ``close()`` disconnects it (idempotent, thread-safe)."""

    __slots__ = ("output", "input", "policy", "storage")

    def __init__(
        self, output: OutputPort[T], input: InputPort[T], policy: ConnPolicy, storage: Storage[T]
    ) -> None:
        self.output = output
        self.input = input
        self.policy = policy
        self.storage = storage

    @property
    def dropped(self) -> int:
        """Samples lost unread on this connection's storage (shared storages share the count)."""
        return self.storage.dropped

    def close(self) -> None:
        """Disconnect this connection; a no-op if already disconnected (also when the same
        pair was connected again since: that newer connection stays)."""
        self.output._remove(self)

    def __repr__(self) -> str:
        return f"<Connection {self.output.qualname} -> {self.input.qualname} [{self.policy}]>"


class ChannelConnection(Connection[T]):
    """A connection into an input port fed from another process: the reader end of a
    channel (a link, a remote writer, a stream; see :mod:`dataflow.transports`) writes
    into its storage, which the port reads like any other. ``output`` is None; ``peer``
    says where the samples come from (for listings)."""

    __slots__ = ("peer",)

    def __init__(self, input: InputPort[T], policy: ConnPolicy, storage: Storage[T], peer: str) -> None:
        super().__init__(None, input, policy, storage)  # type: ignore[arg-type]  # no output port in this process
        self.peer = peer

    def write(self, value: T) -> bool:
        """Store ``value`` (already checked) and wake the port's readers; False when the
        storage refused it (a full BUFFER: counted in :attr:`dropped`). Never blocks."""
        return self.store(0, 0, value)

    def store(self, _n: int, _t_ns: int, value: T) -> bool:
        """:meth:`write`, as a reader end's ``store`` (write number and time are its own).
        Never waits, even where the policy makes writers wait: a transport asks
        :meth:`~dataflow.buffers.Storage.has_room` first and holds its writer back itself."""
        storage = self.storage
        if not storage.write_now(value):
            return False
        for reader in storage.readers:
            if reader._callbacks:
                reader._notify()
        return True

    def close(self) -> None:
        """Detach from the input port (idempotent); what the storage held unread is
        counted as dropped."""
        self.input._detach(self)

    def __repr__(self) -> str:
        return f"<ChannelConnection {self.peer} -> {self.input.qualname} [{self.policy}]>"


class Port(Generic[T]):
    """Common part of ports: name, type, doc, owning task; declared on a TaskContext class as a template.

    Declared on a class, ``task.port_attr`` is that task's own port (a copy made when
    the task is created); created free-standing, it belongs to no task.
    """

    is_input: bool = False
    #: The streams joining this port to topics (:class:`~dataflow.transports.streams.PortStream`;
    #: each adds and removes itself), for ``describe``.
    streams: tuple[PortStream, ...] = ()

    def __init__(self, type: Any, name: str | None = None, doc: str = "") -> None:
        self.type = type
        self.name: str = name or ""
        self.doc = doc
        self.task: TaskContext | None = None
        self.attr: str | None = None
        self._check = registry.checker(type)
        #: Its connections, by the port at their other end (a channel's: by itself).
        self._conns: dict[object, Connection[T]] = {}
        self._refs: dict[int, int] = {}  # id(storage) -> connections of this port using it

    @property
    def type_name(self) -> str:
        """The registry name of the port's type (e.g. ``float64[]``)."""
        return registry.type_name(self.type)

    @property
    def qualname(self) -> str:
        """``task.port`` (or just the port name for a free-standing port)."""
        name = self.name or "<unnamed>"
        return f"{self.task.name}.{name}" if self.task is not None else name

    def __set_name__(self, owner: type, attr: str) -> None:
        self.attr = attr
        if not self.name:
            self.name = attr

    def _clone(self) -> Port[T]:
        raise NotImplementedError

    def connected(self) -> bool:
        """True when at least one connection exists."""
        return bool(self._conns)

    def connection_count(self) -> int:
        """Number of connections of this port."""
        return len(self._conns)

    def connections(self) -> list[Connection[T]]:
        """A snapshot of this port's connections."""
        return list(self._conns.values())

    def disconnect(self) -> None:
        """Remove every connection of this port (idempotent, thread-safe, also while running)."""
        with _setup_lock:
            for conn in list(self._conns.values()):
                conn.close()

    def __repr__(self) -> str:
        kind = "InputPort" if self.is_input else "OutputPort"
        return f"<{kind} {self.qualname}: {self.type_name}>"


class OutputPort(Port[T]):
    """Writes samples to every connected input; never blocks (see module docstring)."""

    is_input = False

    # A class (``OutputPort(float)``, ``OutputPort(list[float])``) types the port's samples
    # for mypy; any other type form (``Annotated[...]``, an array type) leaves them Any.
    @overload
    def __init__(self: OutputPort[T], type: builtins.type[T], name: str | None = None, doc: str = "") -> None: ...
    @overload
    def __init__(self: OutputPort[Any], type: object, name: str | None = None, doc: str = "") -> None: ...

    def __init__(self, type: Any, name: str | None = None, doc: str = "") -> None:
        super().__init__(type, name, doc)
        # (number of writes, last value): one tuple, so a reader on another thread always
        # sees a value with its own write number (remote polling tells new from old by it).
        self._sample: tuple[int, T] = (0, _NONE)
        self._writes = itertools.count(1)
        self._storages: tuple[Storage[T], ...] = ()
        self._single_data: DataObject[T] | None = None  # the one lock-free DATA storage, if so
        self._port_storage: Storage[T] | None = None  # PER_OUTPUT_PORT
        self._shared: Storage[T] | None = None  # SHARED
        #: The channel ends crossing a process (links, subscriptions, streams; see
        #: :mod:`dataflow.transports`): one fan-out, which encodes each sample once for all.
        self._fanout: Fanout[T] | None = None

    def _clone(self) -> OutputPort[T]:
        port: OutputPort[T] = OutputPort(self.type, self.name, self.doc)
        port.attr = self.attr
        return port

    def write(self, value: T) -> WriteStatus:
        """Write ``value`` to every connection; returns a :class:`WriteStatus`.

        Never blocks, thread-safe, lock-free. Raises ``PortTypeError`` (naming the port,
        the expected and the given type) when ``value`` is not of the port's type.
        """
        if type(value) is not self.type:
            value = self._checked(value)
        number = next(self._writes)
        self._sample = (number, value)
        fanout = self._fanout
        if fanout is not None:  # channel ends: after the local connections, never instead
            status = self._write_local(value) if self._storages else _SUCCESS
            return status if fanout.push(number, value) else _FAILURE  # False: a mandatory end refused it
        cell_store = self._single_data
        if cell_store is not None:  # hot path, inlined DataObject.write (keep the two in sync)
            prev = cell_store._cell
            cell_store._cell = [value, True]
            if prev is not None and len(prev) == 2:
                try:
                    prev.pop()
                    cell_store._drops.add()
                except IndexError:
                    pass
            for reader in cell_store.readers:
                if reader._callbacks:
                    reader._notify()
            return _SUCCESS
        storages = self._storages
        if not storages:
            return _NOT_CONNECTED
        status = _SUCCESS
        for storage in storages:
            if storage.write(value):
                for reader in storage.readers:
                    if reader._callbacks:
                        reader._notify()
            elif storage.policy.mandatory:
                status = _FAILURE
        return status

    def _write_local(self, value: T) -> WriteStatus:
        """``write`` to the local connections when channel ends are attached too."""
        status = _SUCCESS
        for storage in self._storages:
            if storage.write(value):
                for reader in storage.readers:
                    if reader._callbacks:
                        reader._notify()
            elif storage.policy.mandatory:
                status = _FAILURE
        return status

    def attach_fanout(self, fanout: Fanout[T] | None) -> None:
        """Make ``fanout`` (a :class:`dataflow.transports.Fanout`) receive every sample
        written from now on, with its write number; None detaches it. Setup path."""
        with _setup_lock:
            self._fanout = fanout
            self._publish(self._storages)

    def _checked(self, value: object) -> T:
        try:
            return self._check(value)
        except TypeError as exc:
            shown = str(exc) or f"{type(value).__name__} {value!r:.60}"  # an array type says its dtype and shape
            raise PortTypeError(f"{self.qualname}: cannot write {shown}; expected {self.type_name}") from None

    def last_written_value(self) -> T | None:
        """The last value written (kept also while unconnected), or None if never written."""
        last = self._sample[1]
        return None if last is _NONE else last

    def last_sample(self) -> tuple[int, T | None]:
        """``(n, value)``: the last value written and how many writes there have been so far
        (0 and None before any). Thread-safe: ``n`` always belongs to ``value``, so a poller
        tells a new sample from an old one even when the same object is written again."""
        n, last = self._sample
        return n, (None if last is _NONE else last)

    def connect_to(self, other: Port[T], policy: ConnPolicy | None = None, *,
                   storage: Storage[T] | None = None) -> Connection[T]:
        """Connect to ``other`` with ``policy`` (default ``ConnPolicy()``); returns the connection.

        Idempotent: connecting an already connected pair returns the existing connection.
        Thread-safe; allowed at any time, also while tasks run. Raises ``PortTypeError``
        when the types differ (naming both ports and types), ``DataflowError`` when
        ``other`` is not an input port or a port-level storage has another policy.
        ``storage``: the connection's own storage, made for ``policy`` by the caller
        (``PER_CONNECTION`` only; e.g. a remote subscriber's inbox, which tags samples
        as they are written).
        """
        policy = policy if policy is not None else ConnPolicy()
        if not isinstance(other, InputPort):
            raise DataflowError(f"{self.qualname}: can only connect to an InputPort, got {other!r}")
        with _setup_lock:
            existing = self._conns.get(other)
            if existing is not None:
                return existing
            if registry.type_name(self.type) != registry.type_name(other.type):
                raise PortTypeError(
                    f"cannot connect {self.qualname} ({self.type_name}) to "
                    f"{other.qualname} ({other.type_name}): types differ"
                )
            if storage is None:
                storage = self._storage_for(other, policy)
            elif policy.buffer_policy is not BufferPolicy.PER_CONNECTION or storage.policy != policy:
                raise DataflowError(f"{self.qualname}: a storage given to connect_to must be made for "
                                    f"{policy} with buffer_policy PER_CONNECTION")
            last = self._sample[1]
            if policy.init and last is not _NONE:
                storage.write(last)
            conn = Connection(self, other, policy, storage)
            self._conns[other] = conn
            other._conns[self] = conn
            if _counted(self._refs, storage, +1):
                self._publish((*self._storages, storage))
            if _counted(other._refs, storage, +1):
                other._publish((*other._sources, storage))
            _rebuild_readers(storage, other)
            return conn

    def _storage_for(self, other: InputPort[T], policy: ConnPolicy) -> Storage[T]:
        bp = policy.buffer_policy
        if bp is BufferPolicy.PER_CONNECTION:
            return make_storage(policy)
        if bp is BufferPolicy.PER_INPUT_PORT:
            storage = other._port_storage = other._port_storage or make_storage(policy)
        elif bp is BufferPolicy.PER_OUTPUT_PORT:
            storage = self._port_storage = self._port_storage or make_storage(policy)
        else:
            storage = self._shared or other._shared or make_storage(policy)
            self._shared = other._shared = storage
        if storage.policy != policy:
            raise DataflowError(
                f"cannot connect {self.qualname} to {other.qualname} with {policy}: "
                f"its {bp.value} storage uses {storage.policy}"
            )
        return storage

    def disconnect(self, other: InputPort[T] | None = None) -> None:
        """Disconnect from ``other`` (or from every input); idempotent, thread-safe."""
        if other is None:
            super().disconnect()
            return
        with _setup_lock:
            conn = self._conns.get(other)
            if conn is not None:
                self._remove(conn)

    def _remove(self, conn: Connection[T]) -> None:
        with _setup_lock:
            if self._conns.get(conn.input) is not conn:
                return
            del self._conns[conn.input]
            del conn.input._conns[self]
            inp = conn.input
            if _counted(self._refs, conn.storage, -1):
                self._publish(_without(self._storages, conn.storage))
            if _counted(inp._refs, conn.storage, -1):
                inp._publish(_without(inp._sources, conn.storage))
            _rebuild_readers(conn.storage)

    def _publish(self, storages: tuple[Storage[T], ...]) -> None:
        """Make ``storages`` the ones writes go to (setup path, under the setup lock)."""
        single = storages[0] if len(storages) == 1 else None
        # Publish in an order that is safe for a concurrent writer: the fast path is
        # cleared before the tuple changes, and set only after it.
        self._single_data = None
        self._storages = storages
        if single is not None and type(single) is DataObject and self._fanout is None:
            self._single_data = single
        if self._port_storage is not None and self._port_storage not in self._storages:
            self._port_storage = None
        if self._shared is not None and self._shared not in self._storages:
            self._shared = None


class InputPort(Port[T]):
    """Reads samples from its connections; never blocks (see module docstring).

    ``event=True`` makes the port an event port: new data triggers the owning task's
    event-driven activity (via a data callback). ``ge``/``gt``/``le``/``lt``/``finite``
    bound what may be written to it from outside (remote writes; see
    :mod:`scart_wire.bounds`: numbers must be finite unless ``finite=False``), and
    ``check(value)``, raising ``ValueError`` with the reason, is the task's own verdict on
    such a value (as a Property's ``check``; its docstring's first line describes it to
    ``scart describe`` and ``scart write``); a task's own connections are not checked.
    """

    is_input = True

    @overload  # as OutputPort's: a class types the samples
    def __init__(
        self: InputPort[T], type: builtins.type[T], name: str | None = None, doc: str = "", event: bool = False, *,
        ge: float | None = None, gt: float | None = None, le: float | None = None, lt: float | None = None,
        finite: bool | None = None, check: Callable[[T], None] | None = None,
    ) -> None: ...
    @overload
    def __init__(
        self: InputPort[Any], type: object, name: str | None = None, doc: str = "", event: bool = False, *,
        ge: float | None = None, gt: float | None = None, le: float | None = None, lt: float | None = None,
        finite: bool | None = None, check: Callable[[Any], None] | None = None,
    ) -> None: ...

    def __init__(
        self, type: Any, name: str | None = None, doc: str = "", event: bool = False, *,
        ge: float | None = None, gt: float | None = None, le: float | None = None, lt: float | None = None,
        finite: bool | None = None, check: Callable[[T], None] | None = None,
    ) -> None:
        super().__init__(type, name, doc)
        self.event = event
        self.bounds: Bounds | None = Bounds.of(type, ge, gt, le, lt, finite)
        #: ``finite=True`` was asked for (not only the default): NaN is refused even from
        #: a transport whose messages may carry it (ROS: :meth:`admit`'s ``nan_ok``).
        self.asks_finite = finite is True
        self.check = check
        #: What ``check`` checks, in words (its docstring's first line; "" without a check).
        self.check_text = _described(check)
        self._sources: tuple[Storage[T], ...] = ()
        self._current = 0
        self._callbacks: tuple[DataCallback[T], ...] = ()
        self._port_storage: Storage[T] | None = None  # PER_INPUT_PORT
        self._shared: Storage[T] | None = None  # SHARED

    def _clone(self) -> InputPort[T]:
        port: InputPort[T] = InputPort(self.type, self.name, self.doc, self.event, check=self.check)
        port.bounds, port.asks_finite = self.bounds, self.asks_finite
        port.attr = self.attr
        return port

    def open_channel(self, policy: ConnPolicy, peer: str) -> ChannelConnection[T]:
        """A new connection into this port fed by a channel's reader end (see
        :class:`ChannelConnection`), with its own storage made for ``policy``. Setup path;
        thread-safe, also while the task runs."""
        storage: Storage[T] = make_storage(policy.with_(buffer_policy=BufferPolicy.PER_CONNECTION))
        conn = ChannelConnection(self, policy, storage, peer)
        with _setup_lock:
            self._conns[conn] = conn  # keyed by itself: no output port here
            if _counted(self._refs, storage, +1):
                self._publish((*self._sources, storage))
            _rebuild_readers(storage, self)
        return conn

    def _detach(self, conn: ChannelConnection[T]) -> None:
        with _setup_lock:
            if self._conns.pop(conn, None) is None:  # keyed by itself, as above
                return
            if _counted(self._refs, conn.storage, -1):
                self._publish(_without(self._sources, conn.storage))
            _rebuild_readers(conn.storage)
        conn.storage.clear()  # unread samples: counted as dropped by the storage

    def admit(self, value: Any, nan_ok: bool = False) -> T:
        """``value`` checked against the port's bounds and ``check`` (a value written from
        outside); raises :class:`~dataflow.errors.PortValueError` naming the port, the
        value and why (its bounds, or the task's reason). ``nan_ok``: NaN and inf are
        legal values where they came from (a ROS message's float fields), so only a port
        that asked for ``finite=True`` refuses them (its limits still hold)."""
        nan_ok = nan_ok and not self.asks_finite
        bounds = self.bounds
        if bounds is not None:
            kind = type(value)
            if not (kind is self.type and (kind is int or (kind is float and (nan_ok or value - value == 0.0))) and
                    bounds.ge is None and bounds.gt is None and bounds.le is None and bounds.lt is None):
                value = self._within_bounds(value, bounds, nan_ok)  # else a number of the port's type, no limits
        if self.check is not None:
            try:
                self.check(value)
            except ValueError as exc:
                raise PortValueError(f"{self.qualname}: rejected {value!r:.80}: {exc}") from None
        return value

    def _within_bounds(self, value: Any, bounds: Bounds, nan_ok: bool) -> Any:
        """``value`` checked against ``bounds`` by pydantic (``nan_ok``: only the limits)."""
        if nan_ok:
            if bounds.ge is None and bounds.gt is None and bounds.le is None and bounds.lt is None:
                return value
            bounds = dataclasses.replace(bounds, finite=False)
        try:
            return bounded_adapter(self.type, bounds).validate_python(value)
        except pydantic.ValidationError as exc:
            raise PortValueError(f"{self.qualname}: {value!r:.80} refused: {exc.errors()[0]['msg']} "
                                 f"(accepts {bounds.text})") from None

    def read(self) -> tuple[FlowStatus, T | None]:
        """The next sample and its :class:`FlowStatus` (see module docstring).

        Never blocks; lock-free; meant for one reading thread per port (the task's).
        """
        sources = self._sources
        n = len(sources)
        if n == 1:
            return sources[0].read()
        if n == 0:
            return _NO_DATA
        return self._read_many(sources, n, newest=False)

    def read_newest(self) -> tuple[FlowStatus, T | None]:
        """Like ``read`` but skips buffered samples to the newest one (skipped count as dropped)."""
        sources = self._sources
        n = len(sources)
        if n == 1:
            return sources[0].read_newest()
        if n == 0:
            return _NO_DATA
        return self._read_many(sources, n, newest=True)

    def _read_many(
        self, sources: tuple[Storage[T], ...], n: int, newest: bool
    ) -> tuple[FlowStatus, T | None]:
        cur = self._current if self._current < n else 0
        first = sources[cur].read_newest() if newest else sources[cur].read()
        if first[0] is _NEW:
            return first
        for k in range(1, n):
            i = (cur + k) % n
            result = sources[i].read_newest() if newest else sources[i].read()
            if result[0] is _NEW:
                self._current = i
                return result
        return first

    def clear(self) -> None:
        """Forget every stored sample: the next read is NO_DATA until a new write."""
        for storage in self._sources:
            storage.clear()

    def add_data_callback(self, callback: DataCallback[T]) -> None:
        """Call ``callback(port)`` in the writer's thread after each sample stored for this port.

        The callback must be cheap and never block (e.g. set an Event). Thread-safe.
        """
        with _setup_lock:
            self._callbacks = (*self._callbacks, callback)

    def remove_data_callback(self, callback: DataCallback[T]) -> None:
        """Remove a callback added before (idempotent)."""
        with _setup_lock:
            cbs = list(self._callbacks)
            if callback in cbs:
                cbs.remove(callback)
            self._callbacks = tuple(cbs)

    def _notify(self) -> None:
        for cb in self._callbacks:
            try:
                cb(self)
            except Exception:  # a reader's callback must never break its writer
                log.exception("data callback %r of %s raised", cb, self.qualname)

    def _publish(self, sources: tuple[Storage[T], ...]) -> None:
        """Make ``sources`` the ones reads come from (setup path, under the setup lock).
        Keeps reading from the current channel across connects/disconnects (as RTT does):
        a port that holds data must not answer NO_DATA because an unrelated peer came."""
        old = self._sources
        current = old[self._current] if self._current < len(old) else None
        self._sources = sources
        if len(self._sources) == 1:  # hot path: read() is the storage's own read
            self.read = self._sources[0].read  # type: ignore[method-assign]  # the hot path: the storage's own
            self.read_newest = self._sources[0].read_newest  # type: ignore[method-assign]  # (as read)
        else:
            self.__dict__.pop("read", None)
            self.__dict__.pop("read_newest", None)
        if self._port_storage is not None and self._port_storage not in self._sources:
            self._port_storage = None
        if self._shared is not None and self._shared not in self._sources:
            self._shared = None
        try:
            self._current = self._sources.index(current) if current is not None else 0
        except ValueError:
            self._current = 0


def _counted(refs: dict[int, int], storage: object, delta: int) -> bool:
    """Count one more (``delta=+1``) or one less (-1) connection of a port using ``storage``;
    True when the storage joins or leaves the port's set (several connections may share one
    storage: PER_INPUT_PORT, PER_OUTPUT_PORT, SHARED). O(1)."""
    key = id(storage)
    n = refs.get(key, 0) + delta
    if n > 0:
        refs[key] = n
    else:
        refs.pop(key, None)
    return (n == 1 and delta > 0) or (n <= 0 and delta < 0)


def _without(storages: tuple[Storage[T], ...], storage: Storage[T]) -> tuple[Storage[T], ...]:
    """``storages`` without ``storage`` (found by identity, at C speed)."""
    i = storages.index(storage)
    return storages[:i] + storages[i + 1:]


def _rebuild_readers(storage: Storage[T], extra: InputPort[T] | None = None) -> None:
    """Recompute which inputs a storage feeds (for data callbacks); setup path only."""
    readers = [inp for inp in storage.readers if storage in inp._sources]
    if extra is not None and storage in extra._sources and extra not in readers:
        readers.append(extra)
    storage.readers = tuple(readers)


def _described(check: Callable[..., object] | None) -> str:
    """A check in words: its docstring's first line, else its name; "" for no check."""
    if check is None:
        return ""
    doc = (getattr(check, "__doc__", None) or "").strip()
    return doc.splitlines()[0].strip() if doc else f"checked by {getattr(check, '__name__', 'a function')}"
