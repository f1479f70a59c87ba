"""Client side of a remote subscription (private; built by ``GrpcComponentProxy.subscribe``).

The stream comes over the policy's transport (see :mod:`dataflow.transports`; ``auto``:
the deployer's ipc socket when both are on one host, else a gRPC ``Subscribe`` stream)
into the subscription's reader end, which decodes each sample once and keeps it in a
policy-shaped :class:`Mailbox` — DATA keeps only the newest, so a slow observer never
sees a backlog; BUFFER(n) holds n and counts the rest. Two owned threads: the
*connector* finds the deployer (through the name service), opens the stream and opens it
again after a failure; the *dispatcher* calls the observer. On ipc the samples arrive
in the process's one io thread, on gRPC in the connector's.

Every sample carries its port's write number and the stream its deployer's boot id, so
every write not received shows as a jump — dropped by the deployer, written while the
stream was cut, or written by a restarted deployer before the stream was back — and the
deployer's heartbeats tell what it could not send since its last sample. ``dropped`` is
thus the writes not delivered, each once. A peer silent for 3 heartbeats is treated as
frozen: the stream is cancelled and re-established, and the gap is reported.
``subscribe`` returns only once the deployer has connected the port (or raises).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import grpc

from scart_wire import codec
from dataflow.errors import DataflowError
from dataflow.policy import ConnPolicy, FlowStatus
from dataflow.remote import errors
from scart_wire import rpc
from dataflow.remote._convert import policy_to_msg
from dataflow.remote._delivery import Dispatcher, Mailbox
from dataflow.remote._links import failure_reason
from dataflow.remote.api import GapEvent, Observer, SampleEvent, Subscription
from dataflow.threads import OwnedThread
from dataflow.transports import NoTransportError, Peer, TransportError, carry
from dataflow.transports.ends import ReaderEnd

if TYPE_CHECKING:
    from dataflow.remote.client import GrpcComponentProxy
    from dataflow.transports.frames import Frame

log = logging.getLogger(__name__)

#: What a peer's failure looks like to the connector (it backs off and reconnects).
PEER_FAILURES = (grpc.RpcError, DataflowError, OSError)


class GrpcSubscription(Subscription):
    """A push (or, with ``period``, polling) subscription over the policy's transport.

    Counters: :attr:`delivered` (observer calls), :attr:`dropped` (writes not delivered:
    not received, undecodable, or dropped by the mailbox), :attr:`decode_errors`,
    :attr:`polls` and :attr:`wasted_polls` (polls that found nothing new), :attr:`reconnects`.

    Raises from the constructor (after closing itself) what the first attempt failed
    with when retrying cannot help, or :class:`~dataflow.remote.errors.RemoteTimeoutError`
    when not connected within the system's timeout.
    """

    def __init__(self, proxy: GrpcComponentProxy, port: str, observer: Observer, policy: ConnPolicy,
                 period: float | None, on_gap: Callable[[GapEvent], None] | None) -> None:
        super().__init__(proxy.name, port, policy, period)
        self._proxy = proxy
        self._system = proxy.system
        self._observer = observer
        self._on_gap = on_gap
        self.heartbeat = self._system.heartbeat_ms / 1000.0
        self._mailbox: Mailbox[SampleEvent] = Mailbox(policy)
        self.closed = threading.Event()
        self._connected = False
        self._settled = threading.Event()  # connected, or failed for good (first attempt)
        self._first_error: BaseException | None = None
        self._gap_start: float | None = None
        self._gap_reason = ""
        self._last_seen = time.monotonic()
        self._peer: Peer | None = None
        self.polls = 0
        self.wasted_polls = 0
        self.reconnects = 0
        label = f"{proxy.name}.{port}"
        self._end = ReaderEnd(f"subscription to {label}", codec.decode, self._store, lambda: self._mailbox.dropped,
                              init=policy.init)
        self._end.on_frame = self._on_frame
        self._dispatcher = Dispatcher(f"scart-sub-{label}", self._mailbox, self._deliver, idle=self.heartbeat,
                                      on_idle=self._watchdog)
        self._connector = OwnedThread(self._run, f"scart-recv-{label}", wake=self._cancel)
        self._system.own(self)
        self._dispatcher.start()
        self._connector.start()
        # return only once connected on the task's side (bounded by the system's timeout)
        self._settled.wait(self._system.timeout)
        if not self._connected:
            error = self._first_error or errors.RemoteTimeoutError(
                f"subscription to {label} not connected within {self._system.timeout} s "
                f"({self._gap_reason or 'no answer'})", "DEADLINE_EXCEEDED", self._system.address)
            self.close()
            raise error

    # ---- counters ----------------------------------------------------------------------
    @property
    def dropped(self) -> int:
        return self._end.lost

    @property
    def decode_errors(self) -> int:
        return self._end.refused

    @property
    def connected(self) -> bool:
        return self._connected

    @property
    def transport(self) -> str:
        """How samples come now: the transport's name (``ipc`` on one host, ``grpc``, a plug-in's)."""
        return self._end.transport

    # ---- the reader end's side -----------------------------------------------------------
    def _store(self, n: int, t_ns: int, value: object) -> bool:
        return self._mailbox.put(SampleEvent(self.component, self.port, value, FlowStatus.NEW_DATA, t_ns / 1e9, n))

    def _on_frame(self, message: Frame) -> None:
        self._mark_up(message.boot_id)

    # ---- observer side -----------------------------------------------------------------
    def _deliver(self, event: object) -> None:
        self.delivered += 1
        self._observer(event)  # type: ignore[arg-type]  # its delivery queue holds this subscription's events only

    def _watchdog(self) -> None:
        """Dispatcher idle: cancel a stream whose peer stopped sending heartbeats."""
        peer = self._peer
        if self.period is None and peer is not None and self._connected:
            silent = time.monotonic() - max(self._last_seen, self._end.seen)
            if silent > 3 * self.heartbeat:
                self._mark_down(f"no heartbeat for {silent:.1f} s (peer frozen?)")
                peer.cancel()

    # ---- connection state --------------------------------------------------------------
    def _mark_up(self, boot_id: str = "") -> None:
        self._last_seen = time.monotonic()
        restarted = bool(boot_id) and bool(self._end.boot_id) and boot_id != self._end.boot_id
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

    # ---- the connector -------------------------------------------------------------------
    def _cancel(self) -> None:
        peer = self._peer
        if peer is not None:
            peer.cancel()

    def _run(self, stopping: threading.Event) -> None:
        backoff = 0.05
        fresh = False
        while not stopping.is_set():
            try:
                address = self._system.resolve(self.component, fresh=fresh)
                if self.period is None:
                    self._stream(address, stopping)
                else:
                    self._poll(stopping)
                backoff = 0.05
                reason = "stream ended by the server"
            except PEER_FAILURES as exc:
                reason = failure_reason(exc)
                if not self._settled.is_set():
                    self._first_error = _first_failure(exc, self._system.address)
                    if self._first_error is not None:
                        self._settled.set()
            except Exception as exc:  # noqa: BLE001 - never let the connector die silently
                log.exception("subscription %s.%s: receiver failed; reconnecting", self.component, self.port)
                reason = failure_reason(exc)
            if stopping.is_set():
                return
            self._mark_down(reason)
            fresh = True
            self.reconnects += 1
            if stopping.wait(backoff):
                return
            backoff = min(1.0, backoff * 2)

    def _stream(self, address: str, stopping: threading.Event) -> None:
        """One stream over the first transport that reaches the deployer, until it ends."""
        peer = Peer(address, self.component, self.port, self._system._stub(address),  # noqa: SLF001
                    self._system.timeout, policy_msg=policy_to_msg(self.policy), policy=self.policy,
                    heartbeat=self.heartbeat)
        self._peer = peer
        if stopping.is_set():
            return
        self._last_seen = time.monotonic()
        try:
            carry(self.policy.transport, lambda t: t.subscribe(self._end, peer),
                  f"{self.component}.{self.port}", PEER_FAILURES, "subscription")
        except NoTransportError as exc:
            raise errors.UnavailableError(str(exc), "UNAVAILABLE", address) from None

    def _poll(self, stopping: threading.Event) -> None:
        """JOrocos-style polling: ReadPort every ``period`` s, deliver what is new."""
        assert self.period is not None
        self._end.transport = "grpc"  # unary ReadPort calls, whatever the policy says
        while not stopping.is_set():
            flow, value, seq, stamp, boot = self._proxy.read_sample_of(self.port)
            self._mark_up(boot)
            self._end.writer(boot)
            self.polls += 1
            if flow is FlowStatus.NEW_DATA and self._end.loss.sample(seq):
                self._mailbox.put(SampleEvent(self.component, self.port, value, flow, stamp / 1e9, seq))
            else:
                self.wasted_polls += 1
            if stopping.wait(self.period):
                return

    def close(self) -> None:
        """Cancel the stream, end both threads; idempotent."""
        if self.closed.is_set():
            return
        self.closed.set()
        self._system.disown(self)
        self._connector.stop()
        self._dispatcher.stop()


def _first_failure(exc: BaseException, address: str) -> BaseException | None:
    """The error to raise from ``subscribe`` when the very first attempt failed for a
    reason retrying cannot fix (refused, unknown, limit reached); None for transient ones."""
    if isinstance(exc, grpc.RpcError) and hasattr(exc, "code"):
        if exc.code() in (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.DEADLINE_EXCEEDED, grpc.StatusCode.CANCELLED):
            return None
        return rpc.translate(exc, address)
    if isinstance(exc, TransportError):  # a plug-in that cannot be loaded, a transport's refusal: final
        return exc
    return None


__all__ = ["GrpcSubscription"]
