"""ipc's serving half (see :mod:`dataflow.transports.serving`), for ``ipc`` and ``shm``
alike: the one-time tickets a deployer hands out through its control plane —
``OpenIpcWriter`` (a link into one of its input ports; role ``operate``) and
``OpenIpcReader`` (a subscription of one of its output ports; role ``read``) — to a
caller on its own host. The connections they open are served by the deployer's ipc
socket (:class:`~._serve.IpcServer`), started with the first ticket and stopped with
the deployer.
"""

from __future__ import annotations

import threading

import grpc

from dataflow.policy import ConnPolicy
from dataflow.transports.ipc._serve import IpcServer
from dataflow.transports.ipc._shm_conns import carries_large
from dataflow.transports.ipc._shm_serve import ShmFlavour
from dataflow.transports.ipc._slots import available as shm_available
from dataflow.transports.ipc._wire import available, host_id
from dataflow.transports.limits import check_fits
from dataflow.transports.served import Served
from dataflow.transports.serving import ChannelHost, Serving
from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb
from scart_wire.rpc import Abort, MethodHandler, abort, peer_key

__all__ = ["IpcServing"]

OpenRequest = pb.OpenIpcWriterRequest | pb.OpenIpcReaderRequest


class IpcServing(Serving):
    """A deployer's ipc tickets, and the socket they open (see the module docstring)."""

    methods = frozenset({"OpenIpcWriter", "OpenIpcReader"})

    def __init__(self, host: ChannelHost) -> None:
        super().__init__(host)
        self._server: IpcServer | None = None  # started with the first ticket
        self._lock = threading.Lock()
        self._stopped = False
        self._host_id = host_id()  # ipc serves callers of this host only

    @property
    def server(self) -> IpcServer | None:
        """The deployer's ipc socket, once a ticket started it (None before, and once stopped)."""
        return self._server

    def handler(self, method: str) -> MethodHandler:
        if method == "OpenIpcWriter":
            return grpc.unary_unary_rpc_method_handler(
                self.open_writer, request_deserializer=pb.OpenIpcWriterRequest.FromString,
                response_serializer=pb.OpenIpcWriterResponse.SerializeToString)
        return grpc.unary_unary_rpc_method_handler(
            self.open_reader, request_deserializer=pb.OpenIpcReaderRequest.FromString,
            response_serializer=pb.OpenIpcReaderResponse.SerializeToString)

    def open_writer(self, request: pb.OpenIpcWriterRequest, context: grpc.ServicerContext) -> pb.OpenIpcWriterResponse:
        """``OpenIpcWriter``: a ticket for a link into ``request.task.port``."""
        try:
            policy = self._admitted(request)
            return pb.OpenIpcWriterResponse(ticket=self._ticket("in", request, policy, 0.0, context))
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)

    def open_reader(self, request: pb.OpenIpcReaderRequest, context: grpc.ServicerContext) -> pb.OpenIpcReaderResponse:
        """``OpenIpcReader``: a ticket for a subscription of ``request.task.port`` (an
        unknown or input port is refused now, by name)."""
        try:
            policy = self._admitted(request)
            port = self.host.output(request.task, request.port)
            check_fits(port, "a subscription")
            if request.shm and policy.transport == "auto" and not carries_large(port.type):
                raise Abort("FAILED_PRECONDITION", f"{port.qualname} carries small samples: ipc, not shm")
            heartbeat = self.host.heartbeat_s(request.heartbeat_ms)  # readers only
            return pb.OpenIpcReaderResponse(ticket=self._ticket("out", request, policy, heartbeat, context))
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)

    def _admitted(self, request: OpenRequest) -> ConnPolicy:
        """The request's policy, once this deployer can serve it: this platform has ipc
        (and shm, when asked), and the caller is on this host."""
        if not available():
            raise Abort("FAILED_PRECONDITION", "this deployer's platform has no ipc transport")
        if not request.host_id or request.host_id != self._host_id:
            raise Abort("FAILED_PRECONDITION", "the caller is on another host: ipc works on one host only")
        policy = self.host.policy(request.policy)
        if request.shm and not shm_available():
            raise Abort("FAILED_PRECONDITION", "this deployer's platform has no anonymous shared memory (shm)")
        return policy

    def _ticket(self, kind: str, request: OpenRequest, policy: ConnPolicy, heartbeat: float,
                context: grpc.ServicerContext) -> pb.IpcTicket:
        server = self._started()
        try:
            secret = server.ticket(kind, request, policy, peer_key(context), heartbeat, context.peer() or "")
        except OverflowError as exc:
            raise Abort("RESOURCE_EXHAUSTED", str(exc)) from None
        return pb.IpcTicket(socket=server.name, secret=secret, boot_id=self.host.boot_id)

    def _serve(self, task: str, port: str, policy: ConnPolicy, who: str, shm: bool) -> Served:
        return self.host.serve(task, port, policy, who, "shm" if shm else "ipc")

    def _started(self) -> IpcServer:
        with self._lock:
            if self._stopped or self.host.stopping.is_set():
                raise Abort("UNAVAILABLE", "this deployer is stopping")
            if self._server is None:
                self._server = IpcServer(self.host.boot_id, self.host.sinks, self._serve, self.host.served.close,
                                         ShmFlavour())
            return self._server

    def stop(self) -> None:
        with self._lock:
            self._stopped = True
            server, self._server = self._server, None
        if server is not None:
            server.stop()
