"""The two sides of ``binding.grpc`` (private; see :mod:`scart.bindings.grpc` for the XML and the
call protocol): :class:`GrpcServiceBinding` exports a component service on a shared
server (:mod:`._server`), :class:`GrpcReferenceBinding` calls one, with callbacks on the
calls' own streams."""

from __future__ import annotations

import itertools
import logging
import queue
import threading
import uuid
import weakref
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

import grpc

from scart_wire import codec

from scart_wire.security import tls_mismatch
from dataflow.threads import OwnedThread
from scart.errors import InvocationError, ServiceUnavailableError
from scart.bindings.grpc._server import Exported, GrpcServer, ServerTable
from scart.bindings.grpc._wire import (
    Reader, UnknownSessionError, decode, failure, fill_invocation, outcome_of, pb, pb_grpc, signatures,
)
from scart.spi import Binding, Host, InterfaceInfo, Invoker, Operation, ReferenceBinding, ServiceBinding, ServiceEndpoint

log = logging.getLogger("scart.bindings.grpc")
T = TypeVar("T")

DEFAULT_SERVICE_ADDRESS = "127.0.0.1:0"
DEFAULT_CALL_TIMEOUT_S = 5.0
DEFAULT_CALLBACK_TIMEOUT_S = 30.0

CHANNEL_OPTIONS: tuple[tuple[str, int], ...] = (
    ("grpc.initial_reconnect_backoff_ms", 100),
    ("grpc.min_reconnect_backoff_ms", 100),
    ("grpc.max_reconnect_backoff_ms", 1000),
    ("grpc.keepalive_time_ms", 5000),
    ("grpc.keepalive_timeout_ms", 5000),
    ("grpc.keepalive_permit_without_calls", 1),
    ("grpc.http2.max_pings_without_data", 0),
    ("grpc.enable_retries", 0),
)



def _timeout(model: Binding | None, default: float) -> float:
    raw = model.attributes.get("timeout") if model is not None else None
    return float(raw) if raw else default


# --- service side ------------------------------------------------------------------------


class GrpcServiceBinding(ServiceBinding):
    """Exports a component service over gRPC (see the module docstring).

    ``start()`` raises ``ScartError`` naming the address when it cannot listen;
    ``stop()`` is idempotent and blocks until the server (if this was its last service)
    has stopped. Thread-safe."""

    def __init__(self, model: Binding, endpoint: ServiceEndpoint, host: Host) -> None:
        super().__init__(model, endpoint, host)
        self.configured_address = model.attributes.get("address") or DEFAULT_SERVICE_ADDRESS
        self.timeout = _timeout(model, DEFAULT_CALLBACK_TIMEOUT_S)
        self._exported = Exported(endpoint, self._names(), host, self.timeout)
        self._server: GrpcServer | None = None
        self._table: ServerTable | None = None

    def _names(self) -> list[str]:
        ep = self.endpoint
        names = [f"{ep.component}/{ep.service}"]
        assembly = self.host.assembly
        node = assembly.nodes.get(ep.component)
        if node is not None and len(node.ctype.services) == 1:
            names.append(ep.component)
        if node is not None:
            names.extend(a for a in node.service_aliases.get(ep.service, ()) if a not in names)
        for name, models in assembly.service_bindings.items():
            if any(m is self.model for m in models):
                names.append(name)
        for name, target in assembly.services.items():  # the names the composite promotes it as
            if (target.node, target.service) == (ep.component, ep.service) and name not in names:
                names.append(name)
        return names

    def start(self) -> None:
        """Listen (or join this runtime's server on the same address)."""
        drain = self.host.drain_timeout
        security = self.host.settings.security
        self._table = self.host.shared("scart.bindings.grpc.servers", lambda: ServerTable(drain, security))
        self._server = self._table.acquire(self.configured_address, self._exported)

    def stop(self) -> None:
        """Stop exporting; the last service of a server stops it. Idempotent."""
        table, self._table = self._table, None
        if table is not None:
            table.release(self.configured_address, self._exported)

    @property
    def address(self) -> str | None:
        """The real "host:port" once started."""
        return self._server.address if self._server is not None else None

    @property
    def names(self) -> list[str]:
        """The names callers may give as ``service``."""
        return list(self._exported.names)

    @property
    def oneway_failures(self) -> int:
        """One-way calls received by this binding that raised in the provider."""
        return self._exported.oneway_failures


# --- reference side ----------------------------------------------------------------------


class GrpcReferenceBinding(ReferenceBinding):
    """Calls a remote service over gRPC (see the module docstring). Invokers are thread-safe."""

    def __init__(self, model: Binding | None, interface: InterfaceInfo, host: Host) -> None:
        super().__init__(model, interface, host)
        attrs = model.attributes if model is not None else {}
        self.target_address = attrs.get("address", "")
        self.service = attrs.get("service", "")
        self.timeout = _timeout(model, DEFAULT_CALL_TIMEOUT_S)
        self.where = f"{self.service or 'service'} at {self.target_address}"
        self._sigs = signatures(interface.python_type, interface.operations)
        cb = interface.callback
        self.callback_sigs = signatures(cb.python_type, cb.operations) if cb is not None else {}
        self._channel: grpc.Channel | None = None
        self._lock = threading.Lock()
        self._session: _ClientSession | None = None
        self._targets: weakref.WeakValueDictionary[int, object] = weakref.WeakValueDictionary()
        self._target_ids = itertools.count(1)
        self._uid = uuid.uuid4().hex[:12]
        self._call_ids = itertools.count(1)

    def start(self) -> None:
        """Create the channel (it connects lazily: an absent provider is not an error yet)."""
        self._channel = self.host.settings.security.channel(self.target_address, CHANNEL_OPTIONS)
        stub = pb_grpc.ScaServiceStub(self._channel)
        self._call, self._send, self._invoke = stub.Call, stub.Send, stub.Invoke
        self._reply, self._open = stub.ReplyCallback, stub.OpenCallbackSession

    def stop(self) -> None:
        """Close the callback session (joins its thread) and the channel. Idempotent."""
        with self._lock:
            session, self._session = self._session, None
            channel, self._channel = self._channel, None
        if session is not None:
            session.close()
        if channel is not None:
            channel.close()

    # --- invokers -----------------------------------------------------------------------

    def invoker(self, operation: Operation, callback: object | None) -> Invoker:
        """One callable for ``operation``: unary ``Call``, ``Send`` (one-way) or the
        callback-carrying ``Invoke`` stream, chosen here once."""
        if not hasattr(self, "_call"):  # never started (the runtime starts references first)
            self.start()
        if callback is not None and self.interface.callback is None:
            callback = None
        if operation.oneway:
            return self._oneway_invoker(operation.name, callback)
        if callback is not None:
            return self._stream_invoker(operation.name, callback)
        return self._unary_invoker(operation.name)

    def _unary_invoker(self, name: str) -> Invoker:
        stub, service, timeout, where = self._call, self.service, self.timeout, self.where
        convert = self._sigs[name].result if name in self._sigs else decode
        fail = self._rpc_failure

        def call(*args: object, **kwargs: object) -> object:
            req = pb.CallRequest()
            inv = req.invocation
            inv.service = service
            inv.operation = name
            if args or kwargs:
                fill_invocation(inv, args, kwargs)
            try:
                out = stub(req, timeout=timeout, wait_for_ready=True).outcome
            except grpc.RpcError as exc:
                raise fail(name, exc) from None
            except ValueError:  # grpc: "Cannot invoke RPC on closed channel!"
                raise InvocationError(f"{where}: {name}: the reference is stopped") from None
            if out.HasField("fault"):
                raise failure(f"{where}: {name}", out.fault)
            return _converted(convert, out.value, where, name)
        call.__qualname__ = f"grpc.{name}"
        return call

    def _oneway_invoker(self, name: str, callback: object | None) -> Callable[..., None]:
        stub, service, timeout, where = self._send, self.service, self.timeout, self.where
        target_id = self._target_id(callback) if callback is not None else 0

        def send(*args: object, **kwargs: object) -> None:
            req = pb.SendRequest()
            inv = req.invocation
            inv.service = service
            inv.operation = name
            fill_invocation(inv, args, kwargs)
            for attempt in (1, 2):  # a second time only when the provider lost our session (restart)
                if callback is not None:
                    inv.session_id = self._ensure_session()
                    inv.target_id = target_id
                try:
                    resp = stub(req, timeout=timeout, wait_for_ready=True)
                except grpc.RpcError as exc:
                    raise self._rpc_failure(name, exc) from None
                except ValueError:  # closed channel
                    raise InvocationError(f"{where}: {name}: the reference is stopped") from None
                if not resp.HasField("fault"):
                    return
                if attempt == 1 and resp.fault.type.endswith(UnknownSessionError.__name__):
                    self._drop_session(inv.session_id)
                    continue
                raise failure(f"{where}: {name}", resp.fault)
        send.__qualname__ = f"grpc.{name}"
        return send

    def _stream_invoker(self, name: str, callback: object) -> Invoker:
        convert = self._sigs[name].result if name in self._sigs else decode
        target_id = self._target_id(callback)

        def call(*args: object, **kwargs: object) -> object:
            req = pb.InvokeRequest()
            inv = req.invocation
            inv.service = self.service
            inv.operation = name
            fill_invocation(inv, args, kwargs)
            session = self._session
            if session is not None and not session.closed.is_set():
                inv.session_id, inv.target_id = session.id, target_id
            return _converted(convert, self._run_stream(name, req, callback), self.where, name)
        call.__qualname__ = f"grpc.{name}"
        return call

    def _run_stream(self, name: str, req: pb.InvokeRequest, callback: object) -> codec.Value:
        req.call_id = call_id = f"{self._uid}-{next(self._call_ids)}"
        try:
            responses = self._invoke(req, timeout=self.timeout, wait_for_ready=True)
        except ValueError:  # closed channel
            raise InvocationError(f"{self.where}: {name}: the reference is stopped") from None
        try:
            for resp in responses:  # bounded by the call's deadline
                if resp.HasField("callback_call"):
                    reply = self.run_callback(callback, resp.callback_call)
                    if reply is not None:
                        self._reply(pb.ReplyCallbackRequest(call_id=call_id, reply=reply), timeout=self.timeout,
                                    wait_for_ready=True)
                    continue
                if resp.outcome.HasField("fault"):
                    raise failure(f"{self.where}: {name}", resp.outcome.fault)
                return resp.outcome.value
        except grpc.RpcError as exc:
            raise self._rpc_failure(name, exc) from None
        finally:
            responses.cancel()
        raise InvocationError(f"{self.where}: {name}: the call ended without a result")

    # --- callbacks ----------------------------------------------------------------------

    def run_callback(self, callback: object | None, cc: pb.CallbackCall) -> pb.CallbackReply | None:
        """Run one ``CallbackCall`` on ``callback`` (None: the session target it names);
        returns the ``CallbackReply`` (None for one-way callbacks, whose errors are logged)."""
        target = callback if callback is not None else self._targets.get(cc.target_id)
        sig = self.callback_sigs.get(cc.operation)

        def run() -> object:
            fn = getattr(target, cc.operation, None)
            if sig is None or fn is None:
                raise InvocationError(f"no callback operation {cc.operation!r} here (or its target is gone)")
            return fn(*sig.args(cc.args), **sig.kwargs(cc.kwargs))
        outcome = outcome_of(run)
        if cc.oneway:
            if outcome.HasField("fault"):
                log.error("one-way callback %s from %s failed: %s: %s", cc.operation, self.where,
                          outcome.fault.type, outcome.fault.message)
            return None
        return pb.CallbackReply(id=cc.id, outcome=outcome)

    def _target_id(self, callback: object) -> int:
        with self._lock:
            for tid, known in self._targets.items():
                if known is callback:
                    return tid
            tid = next(self._target_ids)
            self._targets[tid] = callback
            return tid

    def _ensure_session(self) -> str:
        with self._lock:
            session = self._session
            if session is not None and not session.closed.is_set():
                return session.id
            if self._channel is None:
                raise InvocationError(f"{self.where}: the reference is stopped")
            session = _ClientSession(self)
            try:
                session.open(self.timeout)
            except BaseException:
                session.close()
                raise
            self._session = session
            return session.id

    def _drop_session(self, session_id: str) -> None:
        with self._lock:
            session = self._session
            if session is None or session.id != session_id:
                return
            self._session = None
        session.close()

    def _rpc_failure(self, name: str, exc: grpc.RpcError) -> InvocationError:
        code = exc.code() if isinstance(exc, grpc.Call) else None
        if code == grpc.StatusCode.DEADLINE_EXCEEDED:
            return ServiceUnavailableError(
                f"binding.grpc: {self.where}: {name}: no answer within {self.timeout} s "
                f"(the operation may have run) (DEADLINE_EXCEEDED)")
        if code == grpc.StatusCode.UNAVAILABLE:
            mismatch = tls_mismatch(self.target_address, exc.details() or "") if isinstance(exc, grpc.Call) else None
            if mismatch is not None:  # no use retrying: one side speaks TLS, the other does not
                return InvocationError(f"binding.grpc: {self.where}: {name}: {mismatch}")
            return ServiceUnavailableError(f"binding.grpc: {self.where}: {name}: unreachable (UNAVAILABLE)")
        details = exc.details() if isinstance(exc, grpc.Call) else str(exc)
        return InvocationError(f"binding.grpc: {self.where}: {name}: {code.name if code else 'error'}: {details}")


def _converted(convert: Reader, value: codec.Value, where: str, name: str) -> object:
    """``convert(value)``; a result this side cannot decode or coerce is an ``InvocationError``
    naming the service and operation."""
    try:
        return convert(value)
    except Exception as exc:  # noqa: BLE001 - any decoder/coercion failure
        raise InvocationError(f"binding.grpc: {where}: {name}: cannot convert the result "
                              f"({value.type_name or 'untyped'}): {type(exc).__name__}: {exc}") from exc


def _drain(outbox: queue.SimpleQueue[T | None]) -> Iterator[T]:
    """Yield what is put in ``outbox`` until None (always put in a ``finally``)."""
    while True:
        item = outbox.get()
        if item is None:
            return
        yield item


class _ClientSession:
    """The client end of a callback session: a stream and the thread that runs callbacks."""

    def __init__(self, binding: GrpcReferenceBinding) -> None:
        self.id = uuid.uuid4().hex
        self._binding = binding
        self._outbox: queue.SimpleQueue[pb.OpenCallbackSessionRequest | None] = queue.SimpleQueue()
        self.opened = threading.Event()
        self.closed = threading.Event()
        self._call: Any = None
        self.error: str = ""
        self._thread = OwnedThread(self._read, f"scart-grpc-callbacks-{self.id[:8]}")

    def open(self, timeout: float) -> None:
        """Open the stream and wait (at most ``timeout``) for the server to register it."""
        self._outbox.put(pb.OpenCallbackSessionRequest(session_id=self.id))
        self._call = self._binding._open(_drain(self._outbox), wait_for_ready=True)
        self._thread.start()
        if not self.opened.wait(timeout) or self.closed.is_set():
            if self.error:
                raise InvocationError(f"binding.grpc: {self._binding.where}: cannot open a callback session: "
                                      f"{self.error}")
            raise ServiceUnavailableError(f"binding.grpc: {self._binding.where}: cannot open a callback session "
                                          f"within {timeout} s")

    def _read(self, _stopping: threading.Event) -> None:
        try:
            for resp in self._call:  # ends with the stream (closed by us, or the provider went away)
                if resp.HasField("opened"):
                    self.opened.set()
                    continue
                reply = self._binding.run_callback(None, resp.callback_call)
                if reply is not None:
                    self._outbox.put(pb.OpenCallbackSessionRequest(callback_reply=reply))
        except grpc.RpcError as exc:
            if isinstance(exc, grpc.Call) and exc.code() == grpc.StatusCode.RESOURCE_EXHAUSTED:
                self.error = f"RESOURCE_EXHAUSTED: {exc.details()}"
            if not self.closed.is_set():
                log.info("callback session with %s ended: %s", self._binding.where, exc.code() if isinstance(exc, grpc.Call) else exc)
        finally:
            self.closed.set()
            self.opened.set()  # wake open(): it sees closed
            self._outbox.put(None)

    def close(self) -> None:
        """Cancel the stream and join the reader thread (unless called from it). Idempotent."""
        self.closed.set()
        self._outbox.put(None)
        if self._call is not None:
            self._call.cancel()
        self._thread.stop()


__all__ = ["GrpcReferenceBinding", "GrpcServiceBinding"]
