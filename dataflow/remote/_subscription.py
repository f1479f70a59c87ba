"""Client side of a remote subscription (private; built by ``GrpcComponentProxy.subscribe``).

The stream comes over the policy's transport (see :mod:`dataflow.remote.transport`;
``auto``: the deployer's ipc socket when both are on one host, else a gRPC ``Subscribe``
stream); every transport hands over the same ``SubscribeResponse`` messages, handled alike.
Two threads per subscription: the *receiver* owns the stream (or the polling loop),
puts samples into a policy-shaped :class:`Mailbox` and reconnects after failures; the
*dispatcher* calls the observer. With DATA the mailbox keeps only the newest sample, so
a slow observer never sees a backlog; with BUFFER(n) it holds n and counts the rest as
dropped; the server's own connection does the same on the task's side and reports its
drops in every message. Every sample also carries its port's write number and the
stream its deployer's boot id, so every write not received shows as a jump in the write
numbers — whether the server dropped it or it was written while the stream was cut (a
frozen peer, a reconnection) — and the jumps are the count, each write once. The
server's report only adds the drops no later sample has revealed yet (its last ones).
``dropped`` is thus the writes not delivered. A peer silent for 3 heartbeats is treated
as frozen: the stream is cancelled and re-established (through the name service), and
the gap is reported.
A sample that cannot be decoded is logged and counted as dropped; any other receiver
failure is logged and the stream re-established — the receiver never dies silently.
``subscribe`` returns only once the server has connected the port (or raises).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import grpc

from dataflow import codec
from dataflow.errors import DataflowError
from dataflow.policy import ConnPolicy, FlowStatus
from dataflow.remote import _rpc, errors
from dataflow.remote._loss import LossCount
from dataflow.remote._delivery import Dispatcher, Mailbox
from dataflow.remote.api import GapEvent, Observer, SampleEvent, Subscription
from dataflow.remote.transport import TransportError, carry

if TYPE_CHECKING:
    from dataflow.remote.client import GrpcComponentProxy

log = logging.getLogger(__name__)


class GrpcSubscription(Subscription):
    """A push (or, with ``period``, polling) subscription over gRPC.

    Counters: :attr:`delivered` (observer calls), :attr:`dropped` (server, mailbox and
    undecodable samples), :attr:`decode_errors`, :attr:`polls` and :attr:`wasted_polls`
    (polls that found nothing new), :attr:`reconnects`.

    Raises from the constructor (after closing itself) what the first attempt failed
    with when retrying cannot help, or :class:`~dataflow.remote.errors.RemoteTimeoutError`
    when not connected within the system's timeout.
    """

    def __init__(
        self,
        proxy: GrpcComponentProxy,
        port: str,
        observer: Observer,
        policy: ConnPolicy,
        period: float | None,
        on_gap: Callable[[GapEvent], None] | None,
    ) -> None:
        super().__init__(proxy.name, port, policy, period)
        self._proxy = proxy
        self._system = proxy.system
        self._observer = observer
        self._on_gap = on_gap
        self.heartbeat = self._system.heartbeat_ms / 1000.0
        self._mailbox: Mailbox[SampleEvent] = Mailbox(policy)
        self.closed = threading.Event()
        self._cancel: Callable[[], None] | None = None  # ends the current stream (set by its transport)
        #: How samples come now: the transport's name (``ipc`` on one host, ``grpc``, a plug-in's).
        self.transport = ""
        self._connected = False
        self._settled = threading.Event()  # connected, or failed for good (first attempt)
        self._first_error: BaseException | None = None
        self._gap_start: float | None = None
        self._gap_reason = ""
        self._last_seen = time.monotonic()
        self._boot = ""  # the deployer process the sequence numbers belong to
        self._loss = LossCount()
        self.polls = 0
        self.wasted_polls = 0
        self.reconnects = 0
        self.decode_errors = 0
        label = f"{proxy.name}.{port}"
        self._dispatcher = Dispatcher(
            f"scart-sub-{label}", self._mailbox, self._deliver, idle=self.heartbeat, on_idle=self._watchdog
        )
        self._receiver = threading.Thread(target=self._run, name=f"scart-recv-{label}", daemon=True)
        self._system.own(self)
        self._dispatcher.start()
        self._receiver.start()
        # return only once connected on the task's side (bounded by the system's timeout)
        self._settled.wait(self._system.timeout)
        if not self._connected:
            error = self._first_error or errors.RemoteTimeoutError(
                f"subscription to {label} not connected within {self._system.timeout} s "
                f"({self._gap_reason or 'no answer'})",
                "DEADLINE_EXCEEDED", self._system.address,
            )
            self.close()
            raise error

    # ---- counters ----------------------------------------------------------------------
    @property
    def dropped(self) -> int:
        return self._loss.lost + self._mailbox.dropped + self.decode_errors

    @property
    def connected(self) -> bool:
        return self._connected

    # ---- observer side -----------------------------------------------------------------
    def _deliver(self, event: object) -> None:
        self.delivered += 1
        self._observer(event)  # type: ignore[arg-type]

    def _watchdog(self) -> None:
        """Dispatcher idle: cancel a stream whose peer stopped sending heartbeats."""
        cancel = self._cancel
        if self.period is None and cancel is not None and self._connected:
            silent = time.monotonic() - self._last_seen
            if silent > 3 * self.heartbeat:
                self._mark_down(f"no heartbeat for {silent:.1f} s (peer frozen?)")
                cancel()

    # ---- connection state --------------------------------------------------------------
    def _mark_up(self, boot_id: str = "") -> None:
        self._last_seen = time.monotonic()
        restarted = bool(boot_id) and bool(self._boot) and boot_id != self._boot
        if boot_id:
            if restarted:
                self._loss.restarted()
            self._boot = boot_id
        if self._connected:
            return
        self._connected = True
        self._settled.set()
        if self._gap_start is not None:
            gap = GapEvent(self.component, self.port, self._gap_start, time.time(), self._gap_reason, restarted)
            self._gap_start = None
            with self._lock:
                self._gaps.append(gap)
            log.info("subscription %s.%s resumed after %.2f s (%s)", self.component, self.port, gap.duration, gap.reason)
            if self._on_gap is not None:
                try:
                    self._on_gap(gap)
                except Exception:  # noqa: BLE001
                    log.exception("on_gap callback raised")

    def _mark_down(self, reason: str) -> None:
        if self._gap_start is None and not self.closed.is_set():
            self._gap_start = time.time()
            self._gap_reason = reason
        self._connected = False

    # ---- receiver ----------------------------------------------------------------------
    def _run(self) -> None:
        backoff = 0.05
        fresh = False
        while not self.closed.is_set():
            try:
                address = self._system.resolve(self.component, fresh=fresh)
                if self.period is None:
                    self._stream(address)
                else:
                    self._poll()
                backoff = 0.05
                reason = "stream ended by the server"
            except (grpc.RpcError, DataflowError) as exc:
                reason = _reason(exc)
                if not self._settled.is_set():
                    self._first_error = _first_failure(exc, self._system.address)
                    if self._first_error is not None:
                        self._settled.set()
            except Exception as exc:  # noqa: BLE001 - never let the receiver die silently
                log.exception("subscription %s.%s: receiver failed; reconnecting", self.component, self.port)
                reason = _reason(exc)
            if self.closed.is_set():
                return
            self._mark_down(reason)
            fresh = True
            self.reconnects += 1
            if self.closed.wait(backoff):
                return
            backoff = min(1.0, backoff * 2)

    def _stream(self, address: str) -> None:
        """One stream over the first transport that reaches the deployer (see
        :mod:`dataflow.remote.transport`), until it ends."""
        carry(self.policy.transport, lambda t: t.subscribe(self, address), self._forget,
              f"{self.component}.{self.port}", address)

    def _forget(self) -> None:
        """The transport's stream is over: nothing to cancel any more."""
        self._cancel = None

    # ---- the ReaderEnd a transport sees ------------------------------------------------
    @property
    def heartbeat_ms(self) -> int:
        """The heartbeat period the deployer is asked for (ms)."""
        return self._system.heartbeat_ms

    @property
    def timeout(self) -> float:
        """Deadline (s) of the control-plane calls a transport makes."""
        return self._system.timeout

    def stub(self, address: str) -> Any:
        """The ``DeployerService`` stub of the deployer at ``address``."""
        return self._system._stub(address)  # noqa: SLF001

    def opened(self, transport: str, cancel: Callable[[], None]) -> bool:
        """A new stream is up over ``transport``; ``cancel`` ends it. False when closed meanwhile."""
        self._cancel = cancel
        self.transport = transport
        self._last_seen = time.monotonic()
        if self.closed.is_set():  # close() may have looked before cancel was set
            return False
        self._loss.new_stream()
        return True

    def receive(self, msg: Any) -> None:
        """One ``SubscribeResponse`` (from any transport): its samples into the mailbox."""
        self._mark_up(msg.boot_id)
        for sample in msg.samples:
            if not self._loss.sample(sample.sequence, msg.dropped):
                continue  # already delivered (handed over again after a reconnection)
            try:
                value = codec.decode(sample.value)
            except Exception:  # noqa: BLE001 - one bad sample must not end the stream
                self.decode_errors += 1
                log.exception(
                    "subscription %s.%s: sample %d (%s) cannot be decoded; dropped",
                    self.component, self.port, sample.sequence, sample.value.type_name,
                )
                continue
            event = SampleEvent(
                self.component, self.port, value, FlowStatus.NEW_DATA,
                sample.source_time_ns / 1e9, sample.sequence,
            )
            self._mailbox.put(event)
        self._loss.report(msg.dropped)

    def _poll(self) -> None:
        """JOrocos-style polling: ReadPort every ``period`` s, deliver what is new."""
        assert self.period is not None
        self.transport = "grpc"  # unary ReadPort calls, whatever the policy says
        while not self.closed.is_set():
            flow, value, seq, stamp, boot = self._proxy.read_sample_of(self.port)
            self._mark_up(boot)
            self.polls += 1
            if flow is FlowStatus.NEW_DATA and self._loss.sample(seq):
                self._mailbox.put(SampleEvent(self.component, self.port, value, flow, stamp / 1e9, seq))
            else:
                self.wasted_polls += 1
            if self.closed.wait(self.period):
                return

    def close(self) -> None:
        """Cancel the stream, end both threads (joins ≤ 5 s each); idempotent."""
        if self.closed.is_set():
            return
        self.closed.set()
        self._system.disown(self)
        cancel = self._cancel
        if cancel is not None:
            cancel()  # wakes the receiver
        if threading.current_thread() is not self._receiver:
            self._receiver.join(timeout=5.0)
        self._dispatcher.stop()


def _first_failure(exc: BaseException, address: str) -> BaseException | None:
    """The error to raise from ``subscribe`` when the very first attempt failed for a
    reason retrying cannot fix (refused, unknown, limit reached); None for transient ones."""
    if isinstance(exc, grpc.RpcError) and hasattr(exc, "code"):
        if exc.code() in (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.DEADLINE_EXCEEDED, grpc.StatusCode.CANCELLED):
            return None
        return _rpc.translate(exc, address)
    if isinstance(exc, TransportError):  # a plug-in that cannot be loaded: retrying cannot help
        return exc
    return None


def _reason(exc: BaseException) -> str:
    if isinstance(exc, grpc.RpcError) and hasattr(exc, "code"):
        return f"{exc.code().name}: {exc.details()}"
    return f"{type(exc).__name__}: {exc}"


__all__ = ["GrpcSubscription"]
