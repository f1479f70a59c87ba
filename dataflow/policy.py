"""Connection policies and the statuses of the data-flow hot path (RTT 2.9 ``ConnPolicy``).

A :class:`ConnPolicy` is a frozen value with named constructors; there is no mutable
module-level default. Defaults are RTT 2.9's, including its asymmetry on ``init``:

==============================  ===============  ======  =====  ============  ==============
constructor                     type             size    init   lock_policy   buffer_policy
==============================  ===============  ======  =====  ============  ==============
``ConnPolicy()``                DATA             0       False  LOCK_FREE     PER_CONNECTION
``ConnPolicy.data()``           DATA             0       True   LOCK_FREE     PER_CONNECTION
``ConnPolicy.buffer(n)``        BUFFER           n       False  LOCK_FREE     PER_CONNECTION
``ConnPolicy.circular_buffer(n)`` CIRCULAR_BUFFER n      False  LOCK_FREE     PER_CONNECTION
==============================  ===============  ======  =====  ============  ==============

``init=True`` hands the output's last written value to a connection made later.
``transport`` (RTT's ``ConnPolicy.transport``) says how samples cross processes:
``"auto"`` (default: the fastest that works — ``shm`` for large samples and ``ipc`` for the
rest when both deployers are on one host, else ``grpc``), ``"ipc"`` (the same-host socket),
``"shm"`` (the same-host path with large samples in shared memory), or ``"grpc"``, or a
plug-in's name (:func:`transport_names`: ``"zenoh"``...). A connection
inside one process ignores it. ``topic`` (RTT's ``name_id``) makes a *stream*: the port
joined to a named topic of that transport rather than to another port.
``size`` is at most :data:`MAX_BUFFER`, everywhere.

**Flow control** (YARP's, seed 002 §5): ``wait`` says how the writer behaves when a reader
is behind — :attr:`WaitMode.NO_WAIT` (default: it never waits; a full buffer refuses the
sample, counted), :attr:`WaitMode.WAIT_AFTER` (the write returns once the sample has gone
to every reader: stored in its buffer, waiting for room if need be) or
:attr:`WaitMode.WAIT_BEFORE` (the write first waits until every reader has room, then
hands the sample over) — each wait bounded by ``wait_timeout`` s, after which the sample is
refused and counted. The reader's buffering is the connection type: YARP's
*single-buffer* is ``BUFFER(1)`` (:meth:`ConnPolicy.single_buffer`), *double-buffer*
``BUFFER(2)``, *triple-buffer* (YARP's default: the newest sample always) ``DATA``. A
waiting writer with a single or double buffer delivers every sample, slowed to its
slowest reader; a ``DATA`` reader always has room, so its writer never waits. Across
deployers a link over ``ipc``/``shm`` holds its writer back by its reader's reports
(:mod:`dataflow.transports.flow`), a stream on ``yarp`` by YARP's acknowledgements; a
transport that cannot (``grpc``) refuses such a link at connect.

==============================  =========================  =================================
YARP                            RTT                        ``ConnPolicy``
==============================  =========================  =================================
no-wait writer                  (every RTT writer)         ``wait=NO_WAIT`` (default)
wait-after / wait-before        —                          ``wait=WAIT_AFTER`` / ``WAIT_BEFORE``
single-buffer reader            ``BUFFER(1)``              :meth:`single_buffer`
double-buffer reader            ``BUFFER(2)``              :meth:`double_buffer`
triple-buffer reader (default)  ``DATA``                   :meth:`triple_buffer`, ``data()``
strict reader (keep all)        ``BUFFER(n)``              :meth:`buffer`
newest n                        ``CIRCULAR_BUFFER(n)``     :meth:`circular_buffer`
==============================  =========================  =================================
``mandatory`` (default True, as RTT 2.9: "by default, all connections are mandatory"):
a sample rejected by a mandatory connection makes ``write`` return ``WRITE_FAILURE``;
a non-mandatory connection's rejection is only counted in its ``dropped``.

Where storage lives when ports have several connections (``buffer_policy``, RTT 2.9):

* ``PER_CONNECTION`` (default): each writer→reader pair has its own data object/buffer;
  a reader with several connections drains its current channel, then the others in
  connection order.
* ``PER_INPUT_PORT``: one storage per input port, fed by all its writers (fan-in merge).
* ``PER_OUTPUT_PORT``: one storage per output port, shared by all its readers: a sample
  (buffers) or the newness of a sample (data) is consumed by the first reader.
* ``SHARED``: one storage shared by every writer and reader connected with this policy.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field, replace
from types import MappingProxyType

__all__ = ["ConnType", "LockPolicy", "BufferPolicy", "ConnPolicy", "FlowStatus", "WaitMode", "WriteStatus",
           "MAX_BUFFER", "MAX_WAIT", "TRANSPORTS", "transport_names"]

#: scart's own transport names; plug-ins add theirs (:func:`transport_names`).
TRANSPORTS = ("auto", "ipc", "shm", "grpc")
_TRANSPORT_ALIASES = MappingProxyType({"": "auto"})


#: The largest BUFFER / CIRCULAR_BUFFER a policy may ask for, in one process and across
#: processes alike (a bigger one is refused when the policy is made, naming this limit).
MAX_BUFFER = 100_000
MAX_TOPIC = 256  #: characters of a stream's topic, at most
MAX_WAIT = 60.0  #: seconds a waiting writer may be told to wait for a reader, at most


def transport_names() -> tuple[str, ...]:
    """Every transport name a policy accepts: ``auto``, scart's own, then the plug-ins'
    found through the ``scart.transports`` entry points (see :mod:`dataflow.transports`)."""
    from dataflow.transports import names  # entry points: read once, when first needed

    return (*TRANSPORTS, *(n for n in names() if n not in TRANSPORTS))


def one_of(options: tuple[str, ...]) -> str:
    """``a, b or c``."""
    return f"{', '.join(options[:-1])} or {options[-1]}" if len(options) > 1 else "".join(options)


class ConnType(enum.Enum):
    """What a connection stores: the last sample only, a bounded FIFO, or a ring."""

    DATA = "data"
    BUFFER = "buffer"
    CIRCULAR_BUFFER = "circular"


class LockPolicy(enum.Enum):
    """How a connection's storage is synchronised (see :mod:`dataflow.buffers`)."""

    LOCK_FREE = "lock_free"
    LOCKED = "locked"
    UNSYNC = "unsync"


class BufferPolicy(enum.Enum):
    """Where a connection's storage lives when ports have several connections."""

    PER_CONNECTION = "per_connection"
    PER_INPUT_PORT = "per_input_port"
    PER_OUTPUT_PORT = "per_output_port"
    SHARED = "shared"


class WaitMode(enum.Enum):
    """How a writer behaves when a reader is behind (YARP's flow control; see the module
    docstring): never waits, waits after handing a sample over until every reader has it,
    or waits before until every reader has room."""

    NO_WAIT = "no-wait"
    WAIT_AFTER = "wait-after"
    WAIT_BEFORE = "wait-before"


class FlowStatus(enum.Enum):
    """Result of ``InputPort.read``: nothing ever, an already read sample, or a new one."""

    NO_DATA = 0
    OLD_DATA = 1
    NEW_DATA = 2


class WriteStatus(enum.Enum):
    """Result of ``OutputPort.write``."""

    WRITE_SUCCESS = 0
    WRITE_FAILURE = 1
    NOT_CONNECTED = 2


@dataclass(frozen=True)
class ConnPolicy:
    """How one output→input connection stores and hands over samples (immutable, hashable).

    Raises ``ValueError`` at construction for a buffer of size < 1 or a negative size.
    """

    type: ConnType = ConnType.DATA
    size: int = 0
    lock_policy: LockPolicy = LockPolicy.LOCK_FREE
    init: bool = False
    buffer_policy: BufferPolicy = field(default=BufferPolicy.PER_CONNECTION)
    mandatory: bool = True
    transport: str = "auto"
    topic: str = ""
    wait: WaitMode = WaitMode.NO_WAIT
    wait_timeout: float = 1.0

    def __post_init__(self) -> None:
        transport = _TRANSPORT_ALIASES.get(self.transport, self.transport)
        if transport not in TRANSPORTS:
            if transport not in transport_names():
                raise ValueError(f"ConnPolicy.transport must be {one_of(transport_names())}, got {self.transport!r}")
        object.__setattr__(self, "transport", transport)
        if not isinstance(self.type, ConnType):
            raise ValueError(f"ConnPolicy.type must be a ConnType, got {self.type!r}")
        if self.size < 0:
            raise ValueError(f"ConnPolicy.size must be >= 0, got {self.size}")
        if self.type is not ConnType.DATA and self.size < 1:
            raise ValueError(f"a {self.type.name} connection needs size >= 1, got {self.size}")
        if self.size > MAX_BUFFER:
            raise ValueError(f"ConnPolicy.size {self.size} is over the limit MAX_BUFFER ({MAX_BUFFER} samples)")
        if len(self.topic) > MAX_TOPIC or not self.topic.isprintable():
            raise ValueError(f"ConnPolicy.topic: at most {MAX_TOPIC} printable characters, got {self.topic[:40]!r}")
        if not isinstance(self.wait, WaitMode):
            raise ValueError(f"ConnPolicy.wait must be a WaitMode, got {self.wait!r}")
        if not 0 < self.wait_timeout <= MAX_WAIT:  # also refuses NaN
            raise ValueError(f"ConnPolicy.wait_timeout must be seconds in (0, {MAX_WAIT:g}], got {self.wait_timeout!r}")

    @classmethod
    def data(
        cls,
        lock_policy: LockPolicy = LockPolicy.LOCK_FREE,
        init: bool = True,
        buffer_policy: BufferPolicy = BufferPolicy.PER_CONNECTION,
    ) -> ConnPolicy:
        """Last value only; seeds a new connection with the last written value (RTT default)."""
        return cls(ConnType.DATA, 0, lock_policy, init, buffer_policy)

    @classmethod
    def buffer(
        cls,
        size: int,
        lock_policy: LockPolicy = LockPolicy.LOCK_FREE,
        init: bool = False,
        buffer_policy: BufferPolicy = BufferPolicy.PER_CONNECTION,
    ) -> ConnPolicy:
        """Bounded FIFO of ``size`` samples; a write to a full buffer fails (WRITE_FAILURE)."""
        return cls(ConnType.BUFFER, size, lock_policy, init, buffer_policy)

    @classmethod
    def circular_buffer(
        cls,
        size: int,
        lock_policy: LockPolicy = LockPolicy.LOCK_FREE,
        init: bool = False,
        buffer_policy: BufferPolicy = BufferPolicy.PER_CONNECTION,
    ) -> ConnPolicy:
        """Ring of ``size`` samples; a write to a full ring drops the oldest sample."""
        return cls(ConnType.CIRCULAR_BUFFER, size, lock_policy, init, buffer_policy)

    @classmethod
    def single_buffer(cls, wait: WaitMode = WaitMode.NO_WAIT) -> ConnPolicy:
        """YARP's single-buffer reader: one sample held, ``BUFFER(1)``; with a waiting
        writer (``wait``), nothing is lost."""
        return cls.buffer(1).with_(wait=wait)

    @classmethod
    def double_buffer(cls, wait: WaitMode = WaitMode.NO_WAIT) -> ConnPolicy:
        """YARP's double-buffer reader: one sample being read, one waiting: ``BUFFER(2)``."""
        return cls.buffer(2).with_(wait=wait)

    @classmethod
    def triple_buffer(cls, wait: WaitMode = WaitMode.NO_WAIT) -> ConnPolicy:
        """YARP's triple-buffer reader (its default): the newest sample, ``DATA``; its
        writer never has to wait."""
        return cls.data().with_(wait=wait)

    @classmethod
    def parse(cls, text: str) -> ConnPolicy:
        """Parse the short form ``"data"``, ``"buffer:8"`` or ``"circular:8"``, or YARP's
        reader names ``"single"``, ``"double"``, ``"triple"``; each may end with a writer's
        wait mode: ``"single,wait-before"``, ``"buffer:8,wait-after"``, ``",no-wait"``.

        Raises ``ValueError`` naming the valid forms for anything else.
        """
        body, _, wait = text.strip().lower().partition(",")
        kind, _, size = body.strip().partition(":")
        try:
            mode = WaitMode(wait.strip()) if wait.strip() else WaitMode.NO_WAIT
        except ValueError:
            raise ValueError(f"invalid connection policy {text!r}: a writer's wait is "
                             f"{one_of(tuple(m.value for m in WaitMode))}") from None
        try:
            found = cls._parse_kind(kind, size)
        except ValueError as exc:
            raise ValueError(f"invalid connection policy {text!r}: {exc}") from None
        if found is None:
            raise ValueError(f"invalid connection policy {text!r}: expected 'data', 'buffer:N', 'circular:N', "
                             "'single', 'double' or 'triple', and optionally ',wait-after' or ',wait-before'")
        return found.with_(wait=mode) if mode is not WaitMode.NO_WAIT else found

    @classmethod
    def _parse_kind(cls, kind: str, size: str) -> ConnPolicy | None:
        if kind in ("data", "triple") and not size:
            return cls.data()
        if kind in ("single", "double") and not size:
            return cls.buffer(1 if kind == "single" else 2)
        if kind == "buffer" and size:
            return cls.buffer(int(size))
        if kind in ("circular", "circular_buffer") and size:
            return cls.circular_buffer(int(size))
        return None

    def with_(self, **changes: object) -> ConnPolicy:
        """A copy with some fields changed (the value itself never changes)."""
        return replace(self, **changes)  # type: ignore[arg-type]  # any field by name: __post_init__ checks each

    def __str__(self) -> str:
        text = "data" if self.type is ConnType.DATA else f"{self.type.value}:{self.size}"
        return text if self.wait is WaitMode.NO_WAIT else f"{text},{self.wait.value}"
