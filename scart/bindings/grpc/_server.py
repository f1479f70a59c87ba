"""The provider side of ``binding.grpc`` (private): one gRPC server per address, shared by
the service bindings of a runtime that name that address, and the callback proxies.

Threads: gRPC's server pool (``MAX_WORKERS``; each open ``Invoke`` call and callback
session holds one of its threads for its life, so at most ``MAX_STREAMS`` of them are open
at once, ``MAX_STREAMS_PER_PEER`` from one peer, and a session must say its id within
the first-message deadline of :class:`scart_wire.rpc.StreamBudget`; beyond that RESOURCE_EXHAUSTED, and the rest of the pool stays free
for unary calls), a small pool running ``Invoke`` calls (the stream handler must stay free to send
callback requests while the operation runs; a queued call whose RPC already ended is
skipped, "cancelled before start"), and one reader thread per callback session (matches
replies to waiting callers, so a callback's wait is bounded by ``timeout``). All of them
end in :meth:`GrpcServer.stop`, which waits for running calls at most the runtime's drain
deadline (then logs and abandons them).
"""

from __future__ import annotations

import itertools
import logging
import queue
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeAlias, TypeVar

import grpc

from scart.errors import InvocationError, ScartError, ServiceNotFoundError
from scart_wire.rpc import StreamBudget, bind_problem, server_options
from scart_wire.security import Security, SecurityError, auth_interceptor
from dataflow.threads import OwnedThread
from scart.bindings.grpc._wire import (
    SCA_ROLES,
    Signature, UnknownSessionError, failure, fault, fill_invocation, outcome_of, pb, pb_grpc, signatures,
)
from scart.spi import CURRENT_CALLBACK, Host, InterfaceInfo, Invoker, ServiceEndpoint

log = logging.getLogger("scart.bindings.grpc")
R = TypeVar("R")
#: How a provider's callback reaches its caller: the ``CallbackCall`` sent, the caller's
#: ``Outcome`` back (None for a one-way callback).
SendCallback: TypeAlias = "Callable[[pb.CallbackCall], pb.Outcome | None]"

MAX_WORKERS = 64
MAX_STREAMS = 48  # Invoke calls + callback sessions open at once: the rest of the pool stays for unary calls
MAX_STREAMS_PER_PEER = 36  # from one peer (on loopback, one connection): no one client takes them all
INVOKE_WORKERS = 16
_MAX_CALL_S = 3600.0  # bound of a handler's wait when the client set no deadline


class Exported:
    """One component service on a server: its names, converters and one-way failure count."""

    def __init__(self, endpoint: ServiceEndpoint, names: list[str], host: Host, timeout: float) -> None:
        self.endpoint = endpoint
        self.names = names
        self.host = host
        self.timeout = timeout
        iface = endpoint.interface
        self.sigs = signatures(iface.python_type, iface.operations)
        cb = iface.callback
        self.callback_iface: InterfaceInfo | None = cb
        self.callback_sigs = signatures(cb.python_type, cb.operations) if cb is not None else {}
        self.plain: dict[str, Invoker] = {}
        self.oneway_failures = 0
        self._lock = threading.Lock()

    def call(self, inv: pb.Invocation, callback: object | None) -> object:
        """Run a synchronous operation (any raised error becomes the caller's ``RemoteError``)."""
        name = inv.operation
        sig = self.sigs.get(name)
        if sig is None:
            raise InvocationError(f"{self.names[0]} has no operation {name!r}")
        if callback is None:
            fn = self.plain.get(name)
            if fn is None:
                fn = self.plain[name] = self.endpoint.operation(name, None)
        else:
            fn = self.endpoint.operation(name, callback)
        sig.check_shape(len(inv.args), inv.kwargs)
        return fn(*sig.args(inv.args), **sig.kwargs(inv.kwargs))

    def send(self, inv: pb.Invocation, callback: object | None) -> None:
        """Queue a one-way operation on the runtime's pool; raises if it cannot be queued."""
        name = inv.operation
        sig = self.sigs.get(name)
        if sig is None:
            raise InvocationError(f"{self.names[0]} has no operation {name!r}")
        method = self.endpoint.method(name)
        sig.check_shape(len(inv.args), inv.kwargs)
        args, kwargs = sig.args(inv.args), sig.kwargs(inv.kwargs)

        def work() -> None:
            token = CURRENT_CALLBACK.set(callback)
            try:
                method(*args, **kwargs)
            except BaseException:
                with self._lock:
                    self.oneway_failures += 1
                raise  # the runtime's pool logs it (with the traceback) and counts it too
            finally:
                CURRENT_CALLBACK.reset(token)

        work.__qualname__ = f"{self.names[0]}.{name} (binding.grpc one-way)"
        self.host.submit(work)

    def info(self) -> pb.ServiceInfo:
        """This service as a ``ServiceInfo`` message."""
        iface, cb = self.endpoint.interface, self.callback_iface
        ops = [pb.OperationInfo(name=o.name, oneway=o.oneway, returns_value=o.returns_value,
                                params=self.sigs[o.name].params if o.name in self.sigs else [])
               for o in iface.operations.values()]
        cbs = [pb.OperationInfo(name=o.name, oneway=o.oneway, returns_value=o.returns_value)
               for o in (cb.operations.values() if cb is not None else ())]
        return pb.ServiceInfo(names=self.names, interface=iface.name, operations=ops,
                              callback_interface=cb.name if cb is not None else "", callback_operations=cbs)


class _Callback:
    """The provider's ``scart.callback()`` for a remote caller: one attribute per callback
    operation; each sends a ``CallbackCall`` through ``send`` and (unless one-way) returns
    the decoded, coerced reply.

    Two callbacks to the same caller (same callback session and target) are equal, so a
    provider that keeps its callers in a set or dict keeps one entry per caller, as with
    local callers; without a session each callback is only equal to itself."""

    def __init__(self, exported: Exported, send: SendCallback, target_id: int,
                 session_id: str = "") -> None:
        self._key = (session_id, target_id) if session_id else None
        iface = exported.callback_iface
        for name, op in (iface.operations.items() if iface is not None else ()):
            setattr(self, name, self._make(name, op.oneway, exported.callback_sigs[name], send, target_id))

    @staticmethod
    def _make(name: str, oneway: bool, sig: Signature, send: SendCallback,
              target_id: int) -> Invoker:
        def callback(*args: object, **kwargs: object) -> object:
            cc = pb.CallbackCall(operation=name, oneway=oneway, target_id=target_id)
            fill_invocation(cc, args, kwargs)
            outcome = send(cc)
            if outcome is None:
                return None
            if outcome.HasField("fault"):
                raise failure(f"callback {name}", outcome.fault)
            return sig.result(outcome.value)
        callback.__qualname__ = f"callback.{name}"
        return callback

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, _Callback) or self._key is None:
            return self is other
        return self._key == other._key

    def __hash__(self) -> int:
        return hash(self._key) if self._key is not None else id(self)


class _Awaited:
    """A synchronous callback waiting for its caller's reply: set ``outcome`` (None: no
    reply), then ``arrived``."""

    __slots__ = ("id", "arrived", "outcome")

    def __init__(self, call_id: int) -> None:
        self.id = call_id
        self.arrived = threading.Event()
        self.outcome: pb.Outcome | None = None


class _StreamCallback:
    """Sends callbacks on an ``Invoke`` call's own response stream while the call runs
    (replies arrive by ``ReplyCallback`` → :meth:`deliver`); after it returned, through
    the caller's session (if it named one)."""

    def __init__(self, out: queue.SimpleQueue[pb.InvokeResponse | None], context: grpc.ServicerContext,
                 timeout: float, fallback: SendCallback | None) -> None:
        self._out = out
        self._context = context
        self._timeout = timeout
        self._fallback = fallback
        self._lock = threading.Lock()
        self._ids = itertools.count(1)
        self._waiting: _Awaited | None = None  # the callback awaiting its reply
        self.done = False

    def finish(self) -> None:
        """The call returned or its RPC ended: later callbacks go through the session fallback."""
        self.done = True
        self.deliver(None)

    def deliver(self, reply: pb.CallbackReply | None) -> bool:
        """Hand the caller's ``CallbackReply`` to the waiting callback (None: wake it, no reply)."""
        slot = self._waiting
        if slot is None or (reply is not None and reply.id != slot.id):
            return False
        slot.outcome = reply.outcome if reply is not None else None
        slot.arrived.set()
        return reply is not None

    def send(self, cc: pb.CallbackCall) -> pb.Outcome | None:
        with self._lock:  # one callback at a time on the stream: replies come back in order
            if not self.done:
                cc.id = next(self._ids)
                slot = None if cc.oneway else _Awaited(cc.id)
                self._waiting = slot
                self._out.put(pb.InvokeResponse(callback_call=cc))
                if slot is None:
                    return None
                remaining = self._context.time_remaining()
                slot.arrived.wait(min(self._timeout, remaining) if remaining is not None else self._timeout)
                self._waiting = None
                if slot.outcome is None:
                    raise InvocationError(f"callback {cc.operation}: no reply from the caller (gone, or too slow)")
                return slot.outcome
        if self._fallback is None:
            raise InvocationError(f"callback {cc.operation}: the call has returned and the caller has no callback session")
        return self._fallback(cc)


class _Session:
    """A caller's callback session: ``CallbackCall`` s go out in order; a reader thread
    matches the caller's replies to the waiting senders."""

    def __init__(self, session_id: str, requests: Iterator[pb.OpenCallbackSessionRequest]) -> None:
        self.id = session_id
        self.out: queue.SimpleQueue[pb.OpenCallbackSessionResponse | None] = queue.SimpleQueue()
        self._requests = requests
        self._ids = itertools.count(1)
        self._pending: dict[int, _Awaited] = {}  # by callback id
        self._lock = threading.Lock()
        self.closed = False
        self.reader = OwnedThread(self._read, f"scart-grpc-session-{session_id[:8]}")

    def _read(self, _stopping: threading.Event) -> None:
        try:
            for msg in self._requests:  # ends with the stream
                if msg.HasField("callback_reply"):
                    with self._lock:
                        slot = self._pending.pop(msg.callback_reply.id, None)
                    if slot is not None:
                        slot.outcome = msg.callback_reply.outcome
                        slot.arrived.set()
        except grpc.RpcError:
            pass
        finally:
            self.close()

    def send(self, cc: pb.CallbackCall, timeout: float) -> pb.Outcome | None:
        """Send ``cc``; for a synchronous callback wait (at most ``timeout`` s) for the reply."""
        with self._lock:
            if self.closed:
                raise InvocationError(f"callback {cc.operation}: the caller's callback session is closed")
            cc.id = next(self._ids)
            slot = _Awaited(cc.id)
            if not cc.oneway:
                self._pending[cc.id] = slot
            self.out.put(pb.OpenCallbackSessionResponse(callback_call=cc))
        if cc.oneway:
            return None
        if not slot.arrived.wait(timeout):
            with self._lock:
                self._pending.pop(cc.id, None)
            raise InvocationError(f"callback {cc.operation}: no reply from the caller within {timeout} s")
        if slot.outcome is None:
            raise InvocationError(f"callback {cc.operation}: the caller's callback session closed")
        return slot.outcome

    def close(self) -> None:
        """Close: wake the stream handler and every waiting sender. Idempotent."""
        with self._lock:
            if self.closed:
                return
            self.closed = True
            pending, self._pending = self._pending, {}
        self.out.put(None)
        for slot in pending.values():
            slot.arrived.set()


class GrpcServer:
    """A gRPC server exporting component services (``Exported``) under their names."""

    def __init__(self, address: str, drain_timeout: float = 10.0, security: Security | None = None) -> None:
        self.configured = address
        self.security = security or Security()
        self.drain_timeout = drain_timeout  # the runtime's: bounds how long stop waits for running calls
        self._running: dict[int, str] = {}  # operations running now (for stop's report)
        self._idle = threading.Condition()
        self._run_ids = itertools.count(1)
        self.address: str | None = None
        self._services: dict[str, Exported] = {}
        self._exported: list[Exported] = []
        self._sessions: dict[str, _Session] = {}
        self._calls: dict[str, _StreamCallback] = {}  # Invoke calls running, by the client's call id
        self._lock = threading.Lock()
        self._server: grpc.Server | None = None
        self._invoke_pool: ThreadPoolExecutor | None = None
        self._server_pool: ThreadPoolExecutor | None = None

    # --- lifecycle --------------------------------------------------------------------

    def start(self) -> None:
        """Listen on the configured address (TLS and tokens as the runtime's settings say);
        raises ``ScartError`` naming it if that fails or would be unsafe."""
        try:
            self.security.check_bind(self.configured, "binding.grpc")
            credentials = self.security.server_credentials()
            table = self.security.auth_table()
        except SecurityError as exc:
            raise ScartError(f"binding.grpc: {exc}") from None
        budget = StreamBudget(MAX_STREAMS, MAX_STREAMS_PER_PEER, label="too many callback streams")
        interceptors = [budget.interceptor()]
        if table is not None:
            interceptors.insert(0, auth_interceptor(table, SCA_ROLES))
        self._server_pool = ThreadPoolExecutor(MAX_WORKERS, thread_name_prefix="scart-grpc-server")
        server = grpc.server(self._server_pool, options=server_options(), interceptors=interceptors,
                             maximum_concurrent_rpcs=MAX_WORKERS)  # beyond: RESOURCE_EXHAUSTED, never a queue
        pb_grpc.add_ScaServiceServicer_to_server(_Servicer(self), server)
        problem = bind_problem(self.configured)
        if problem is not None:
            server.stop(None)
            self._server_pool.shutdown(wait=False)
            raise ScartError(f"binding.grpc: {problem}")
        try:
            if credentials is not None:
                port = server.add_secure_port(self.configured, credentials)
            else:
                port = server.add_insecure_port(self.configured)
        except RuntimeError:
            port = 0
        if not port:
            server.stop(None)
            self._server_pool.shutdown(wait=False)
            raise ScartError(f"binding.grpc: cannot listen on {self.configured} (port in use or bad address)")
        host = self.configured.rpartition(":")[0]
        self.address = f"{host}:{port}"
        self._invoke_pool = ThreadPoolExecutor(INVOKE_WORKERS, thread_name_prefix="scart-grpc-invoke")
        self._server = server
        server.start()

    def stop(self) -> None:
        """Stop serving: running calls get the runtime's drain deadline, then are abandoned
        (logged, their threads finish on their own); close sessions, join threads. Idempotent."""
        server, self._server = self._server, None
        if server is None:
            return
        deadline = time.monotonic() + self.drain_timeout
        with self._lock:
            sessions = list(self._sessions.values())
            self._sessions.clear()
        for s in sessions:  # first, so their streams end now instead of using up the grace period
            s.close()
        server.stop(self.drain_timeout).wait(self.drain_timeout + 1.0)
        with self._idle:
            self._idle.wait_for(lambda: not self._running, max(0.0, deadline - time.monotonic()))
            abandoned = sorted(self._running.values())
        if abandoned:
            log.warning("binding.grpc at %s: stop: %d call(s) still running after %.1f s abandoned: %s",
                        self.address, len(abandoned), self.drain_timeout, ", ".join(abandoned))
        for s in sessions:
            s.reader.join(max(0.0, deadline - time.monotonic()))
        if self._invoke_pool is not None:
            self._invoke_pool.shutdown(wait=not abandoned, cancel_futures=True)
        if self._server_pool is not None:
            self._server_pool.shutdown(wait=not abandoned)  # gRPC does not shut down a pool it was given

    def _tracked(self, label: str, fn: Callable[[], R]) -> Callable[[], R]:
        """``fn`` counted as a running call while it runs (stop waits for it, bounded)."""
        def run() -> R:
            key = next(self._run_ids)
            with self._idle:
                self._running[key] = label
            try:
                return fn()
            finally:
                with self._idle:
                    del self._running[key]
                    self._idle.notify_all()
        return run

    def add(self, exported: Exported) -> None:
        """Export a service under its names (a later service does not steal a taken name)."""
        with self._lock:
            self._exported.append(exported)
            for name in exported.names:
                self._services.setdefault(name, exported)

    def remove(self, exported: Exported) -> int:
        """Stop exporting a service; returns how many remain."""
        with self._lock:
            self._exported = [e for e in self._exported if e is not exported]
            self._services = {n: e for n, e in self._services.items() if e is not exported}
            return len(self._exported)

    # --- handlers ---------------------------------------------------------------------

    def _find(self, name: str) -> Exported:
        found = self._services.get(name)
        if found is None:
            exported = self._exported
            if not name and len(exported) == 1:
                return exported[0]
            names = sorted(self._services)
            raise ServiceNotFoundError(f"no service {name!r} at {self.address}; it serves: {', '.join(names) or 'none'}")
        return found

    def _callback_for(self, exported: Exported, inv: pb.Invocation) -> object | None:
        if not inv.session_id or exported.callback_iface is None:
            return None
        return _Callback(exported, self._session_sender(inv.session_id, exported.timeout), inv.target_id,
                         inv.session_id)

    def _session_sender(self, session_id: str, timeout: float) -> SendCallback:
        def send(cc: pb.CallbackCall) -> pb.Outcome | None:
            session = self._sessions.get(session_id)
            if session is None:
                raise InvocationError(f"callback {cc.operation}: the caller's callback session is closed")
            return session.send(cc, timeout)
        return send

    def _call(self, request: pb.CallRequest, context: grpc.ServicerContext) -> pb.CallResponse:
        inv = request.invocation
        if not context.is_active():  # waited for a server thread past the caller's deadline
            log.warning("binding.grpc: %s.%s at %s: cancelled before start (the caller gave up)",
                        inv.service, inv.operation, self.address)
            return pb.CallResponse()

        def run() -> object:
            exported = self._find(inv.service)
            return exported.call(inv, self._callback_for(exported, inv))
        return pb.CallResponse(outcome=outcome_of(self._tracked(f"{inv.service}.{inv.operation}", run)))

    def _send(self, request: pb.SendRequest, context: grpc.ServicerContext) -> pb.SendResponse:
        inv = request.invocation
        try:
            exported = self._find(inv.service)
            if inv.session_id and inv.session_id not in self._sessions:
                raise UnknownSessionError(f"no callback session {inv.session_id} here")
            exported.send(inv, self._callback_for(exported, inv))
        except Exception as exc:
            return pb.SendResponse(fault=fault(exc))
        return pb.SendResponse()

    def _invoke(self, request: pb.InvokeRequest, context: grpc.ServicerContext) -> Iterator[pb.InvokeResponse]:
        inv, call_id = request.invocation, request.call_id
        out: queue.SimpleQueue[pb.InvokeResponse | None] = queue.SimpleQueue()
        cb: _StreamCallback | None = None

        def ended() -> None:  # the RPC ended (outcome sent, deadline, cancel): stop every wait
            out.put(None)
            if cb is not None:
                cb.finish()
        context.add_callback(ended)

        def call() -> object:
            nonlocal cb
            exported = self._find(inv.service)
            fallback = self._session_sender(inv.session_id, exported.timeout) if inv.session_id else None
            cb = _StreamCallback(out, context, exported.timeout, fallback)
            with self._lock:
                self._calls[call_id] = cb
            target = (_Callback(exported, cb.send, inv.target_id, inv.session_id)
                      if exported.callback_iface is not None else None)
            return exported.call(inv, target)

        def run() -> None:
            if not context.is_active():  # the client was already told it failed (deadline, cancel)
                log.warning("binding.grpc: %s.%s at %s: cancelled before start (the caller gave up)",
                            inv.service, inv.operation, self.address)
                out.put(None)
                return
            outcome = outcome_of(self._tracked(f"{inv.service}.{inv.operation}", call))
            if cb is not None:
                cb.finish()
                with self._lock:
                    if self._calls.get(call_id) is cb:
                        del self._calls[call_id]
            out.put(pb.InvokeResponse(outcome=outcome))

        try:
            if self._invoke_pool is None:
                raise RuntimeError("not started")
            self._invoke_pool.submit(run)
        except RuntimeError as exc:
            yield pb.InvokeResponse(outcome=pb.Outcome(fault=fault(ScartError(f"server stopping: {exc}"))))
            return
        while True:  # ends with the outcome, or when the RPC ends
            try:
                item = out.get(timeout=_MAX_CALL_S)
            except queue.Empty:
                return
            if item is None:
                return
            yield item
            if item.HasField("outcome"):
                return

    def _reply(self, request: pb.ReplyCallbackRequest, context: grpc.ServicerContext) -> pb.ReplyCallbackResponse:
        cb = self._calls.get(request.call_id)
        return pb.ReplyCallbackResponse(delivered=cb is not None and cb.deliver(request.reply))

    def _open_session(self, requests: Iterator[pb.OpenCallbackSessionRequest],
                      context: grpc.ServicerContext) -> Iterator[pb.OpenCallbackSessionResponse]:
        first = next(requests, None)
        if first is None or not first.session_id:
            return
        session = _Session(first.session_id, requests)
        with self._lock:
            old = self._sessions.get(session.id)
            self._sessions[session.id] = session
        if old is not None:
            old.close()
        context.add_callback(session.close)
        session.reader.start()
        try:
            yield pb.OpenCallbackSessionResponse(opened=True)
            while True:  # ends when the session closes (client gone, server stopping)
                try:
                    item = session.out.get(timeout=_MAX_CALL_S)
                except queue.Empty:
                    continue
                if item is None:
                    return
                yield item
        finally:
            session.close()
            with self._lock:
                if self._sessions.get(session.id) is session:
                    del self._sessions[session.id]

    def _list(self, request: pb.ListServicesRequest, context: grpc.ServicerContext) -> pb.ListServicesResponse:
        with self._lock:
            exported = list(self._exported)
        return pb.ListServicesResponse(services=[e.info() for e in exported])


class _Servicer(pb_grpc.ScaServiceServicer):
    """The generated servicer interface, answered by a :class:`GrpcServer`."""

    def __init__(self, server: GrpcServer) -> None:
        handlers = {"Call": server._call, "Send": server._send, "Invoke": server._invoke,
                    "ReplyCallback": server._reply, "OpenCallbackSession": server._open_session,
                    "ListServices": server._list}
        for method, handler in handlers.items():  # the generated base's methods, answered by the server's
            setattr(self, method, handler)


class ServerTable:
    """The servers of one runtime, by configured address; reference-counted. Thread-safe."""

    def __init__(self, drain_timeout: float = 10.0, security: Security | None = None) -> None:
        self._lock = threading.Lock()
        self._servers: dict[str, GrpcServer] = {}
        self.drain_timeout = drain_timeout
        self.security = security

    def acquire(self, address: str, exported: Exported) -> GrpcServer:
        """The (started) server for ``address`` with ``exported`` added; raises ``ScartError``."""
        with self._lock:
            server = self._servers.get(address)
            if server is None:
                server = GrpcServer(address, self.drain_timeout, self.security)
                server.start()
                self._servers[address] = server
            server.add(exported)
            return server

    def release(self, address: str, exported: Exported) -> None:
        """Remove ``exported``; the last one out stops the server."""
        with self._lock:
            server = self._servers.get(address)
            if server is None or server.remove(exported):
                return
            del self._servers[address]
        server.stop()
