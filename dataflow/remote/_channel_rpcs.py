"""The RPCs of the sample path (private): how a deployer opens the channels other
processes ask for — subscriptions going out (``Subscribe``, ``OpenIpcReader``) and links
coming in (``Link``, ``OpenIpcWriter``). Everything else its servicer does is the control
plane (:mod:`dataflow.remote._servicer`).

A subscription is a :class:`~dataflow.transports.served.Served` writer end attached to
the output port (never failing the writer); a link coming in is an
:class:`~dataflow.transports.sinks.IncomingLink` reader end whose buffer feeds the input
port. Both are counted in ``ListLinks``, whichever transport carries them.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import grpc

from dataflow.policy import ConnPolicy
from dataflow.remote import _convert as cv
from dataflow.remote._proto import df as pb
from scart_wire.rpc import Abort, abort, peer_key
from dataflow.transports import frames
from dataflow.transports.grpc import Parts, ServedCarrier, serve_subscription
from dataflow.transports.ipc import _wire as ipc_wire
from dataflow.transports.ipc._serve import IpcServer
from dataflow.transports.limits import check_fits
from dataflow.transports.ipc.shm import ShmFlavour, carries_large
from dataflow.transports.ipc.shm import available as shm_available
from dataflow.transports.served import Served, ServedSet
from dataflow.transports.sinks import LINGER_S, REPORT_EVERY, REPORT_S, Refused, Sinks

if TYPE_CHECKING:
    from dataflow.remote.server import DeployerServer

__all__ = ["ChannelRpcs", "MAX_HEARTBEAT_MS", "MIN_HEARTBEAT_MS"]

log = logging.getLogger(__name__)

MIN_HEARTBEAT_MS = 50  #: shortest idle heartbeat a subscriber may ask for
MAX_HEARTBEAT_MS = 10_000  #: longest


class ChannelRpcs:
    """The sample path's RPCs, mixed into the deployer's servicer (see the module docstring)."""

    owner: DeployerServer
    heartbeat_ms: int

    def _init_channels(self, max_streams: int) -> None:
        self.sinks = Sinks(lambda task, port: self.owner.deployer.task(task).port(port))
        self.served = ServedSet(max_streams)
        self._ipc: IpcServer | None = None  # started with the first ipc ticket
        self._ipc_lock = threading.Lock()
        self._channels_stopping = threading.Event()
        self._host_id = ipc_wire.host_id()  # ipc serves callers of this host only

    def _stop_channels(self) -> None:
        """Stop serving the sample path. The incoming links' buffers are counted first,
        and each transport sends its link's source a last report: a source that comes to
        a restarted sink knows what the old one lost (its buffer included), to the sample."""
        self._channels_stopping.set()
        self.sinks.close_all()
        with self._ipc_lock:
            ipc, self._ipc = self._ipc, None
        if ipc is not None:
            ipc.stop()
        self.served.close_all()

    def _output(self, task: str, port: str) -> Any:
        p = self.owner.deployer.task(task).port(port)
        if p.is_input:
            raise Abort("INVALID_ARGUMENT", f"{task}.{port} is an input port; this needs an output port")
        return p

    def _heartbeat_s(self, asked_ms: int) -> float:
        """A reader's heartbeat period (s): what it asked for (else this deployer's), clamped:
        too often is a busy loop, too rare hides a frozen peer."""
        return min(max(asked_ms or self.heartbeat_ms, MIN_HEARTBEAT_MS), MAX_HEARTBEAT_MS) / 1000.0

    def _serve(self, task: str, port: str, policy: ConnPolicy, who: str, transport: str) -> Served:
        output = self._output(task, port)
        check_fits(output, "a subscription")  # every sample would be refused: said now
        try:
            return self.served.open(output, policy, who, transport)
        except OverflowError as exc:
            raise Abort("RESOURCE_EXHAUSTED", str(exc)) from None

    # ---- subscriptions -------------------------------------------------------------------
    def Subscribe(self, request: pb.SubscribeRequest, context: grpc.ServicerContext) -> Iterator[bytes]:  # noqa: N802
        try:
            served = self._serve(request.task, request.port, cv.policy_from_msg(request.policy),
                                 context.peer() or "", "grpc")
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)
        carrier = ServedCarrier(served.end)
        context.add_callback(carrier.wake.set)  # a cancelled stream wakes at once
        try:
            yield from serve_subscription(served.end, carrier, self.owner.boot_id,
                                          self._heartbeat_s(request.heartbeat_ms),
                                          lambda: context.is_active() and not self._channels_stopping.is_set(),
                                          served.end.tail_after)
        finally:
            self.served.close(served)

    # ---- links coming in -----------------------------------------------------------------
    def Link(self, request_iterator: Any, context: grpc.ServicerContext) -> Iterator[Any]:  # noqa: N802
        try:
            first = next(request_iterator)
            policy = cv.policy_from_msg(first.hello.policy)
            link, known = self.sinks.open(first.hello, policy)
        except StopIteration:
            return
        except Refused as exc:
            yield pb.LinkResponse(refused=str(exc))
            return
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)
        link.end.transport = "grpc"
        finished = False
        try:
            yield frames.report_of(link.end, known=known)
            unreported, reported_at = 0, time.monotonic()
            parts = Parts(pb.LinkRequest.FromString)
            for message in request_iterator:
                frame = parts.whole(message)
                if frame is None:  # a part of a large sample
                    link.end.seen = time.monotonic()
                    continue
                unreported += frames.feed(link.end, frame) + 1
                if link.closed and not frame.closing:  # this deployer stops: the last report
                    yield frames.report_of(link.end)
                    return
                if frame.closing:
                    link.linger(time.monotonic() + LINGER_S, self._channels_stopping)
                    finished = True
                    self.sinks.finish(link)
                    yield frames.report_of(link.end, final=True)
                    return
                now = time.monotonic()
                if unreported >= REPORT_EVERY or now - reported_at >= REPORT_S or frame.heartbeat:
                    yield frames.report_of(link.end, pending=link.pending)
                    unreported, reported_at = 0, now
        finally:
            if not finished:
                self.sinks.carried(link)

    # ---- the same-host fast path (see dataflow.transports.ipc) ---------------------------
    def OpenIpcWriter(self, request: pb.OpenIpcWriterRequest, context: grpc.ServicerContext) -> pb.OpenIpcWriterResponse:  # noqa: N802
        return self._open_ipc("in", request, context)

    def OpenIpcReader(self, request: pb.OpenIpcReaderRequest, context: grpc.ServicerContext) -> pb.OpenIpcReaderResponse:  # noqa: N802
        return self._open_ipc("out", request, context)

    def _open_ipc(self, kind: str, request: Any, context: grpc.ServicerContext) -> Any:
        try:
            if not ipc_wire.available():
                raise Abort("FAILED_PRECONDITION", "this deployer's platform has no ipc transport")
            if not request.host_id or request.host_id != self._host_id:
                raise Abort("FAILED_PRECONDITION", "the caller is on another host: ipc works on one host only")
            policy = cv.policy_from_msg(request.policy)
            if kind == "out":
                port = self._output(request.task, request.port)  # an unknown or input port: refused now, by name
                check_fits(port, "a subscription")
                if request.shm and policy.transport == "auto" and not carries_large(port.type):
                    raise Abort("FAILED_PRECONDITION", f"{port.qualname} carries small samples: ipc, not shm")
            if request.shm and not shm_available():
                raise Abort("FAILED_PRECONDITION", "this deployer's platform has no anonymous shared memory (shm)")
            heartbeat = self._heartbeat_s(request.heartbeat_ms) if kind == "out" else 0.0  # readers only
            server = self._ipc_server()
            try:
                ticket = server.ticket(kind, request, policy, peer_key(context), heartbeat, context.peer() or "")
            except OverflowError as exc:
                raise Abort("RESOURCE_EXHAUSTED", str(exc)) from None
            found = pb.IpcTicket(socket=server.name, secret=ticket, boot_id=self.owner.boot_id)
            if kind == "in":
                return pb.OpenIpcWriterResponse(ticket=found)
            return pb.OpenIpcReaderResponse(ticket=found)
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)

    def _serve_ipc(self, task: str, port: str, policy: ConnPolicy, who: str, shm: bool) -> Served:
        return self._serve(task, port, policy, who, "shm" if shm else "ipc")

    def _ipc_server(self) -> IpcServer:
        with self._ipc_lock:
            if self._channels_stopping.is_set():
                raise Abort("UNAVAILABLE", "this deployer is stopping")
            if self._ipc is None:
                self._ipc = IpcServer(self.owner.boot_id, self.sinks, self._serve_ipc, self.served.close, ShmFlavour())
            return self._ipc
