"""ROS 1 services and scart, both ways, through this process's one ROS node (see
:mod:`.transport`).

**A ROS service answered by scart** (:func:`serve`, :func:`serve_operation`; in a
composite ``<scart:rosservice>``): a callable — a task's operation, an SCA service's
operation — answers ``pkg/Srv`` requests. Request fields become the callable's arguments
**by name** (a one-field request and a one-parameter callable pair up whatever their
names); the return value becomes the response: a model or mapping by field names, a plain
value into a one-field response, ``None`` as the response's defaults. A response with
``bool success`` and ``string message`` (``std_srvs/Trigger``, ``SetBool``) follows their
convention: ``None`` or ``True`` is success, a string is the message, an exception is
``success: false`` with its text. Otherwise an exception answers a ROS service error,
which ``rosservice call`` prints. ``converter="module:function"`` replaces all of it:
``function(request, call) -> response`` (a message or a mapping). Types are checked when
the service is made; a task's arguments are checked as any outside input (bounds,
finiteness) before the operation runs, with ``timeout`` s to answer.

**A ROS service called from scart**: :class:`ServiceProxy` (``proxy(**fields)`` returns
the response as plain data, or as a model it is given), :func:`call_service` for one call,
and ``scart call ros1:/service '{"field": value}' [--type pkg/Srv]``. Without a type the
service is asked for it (the ``probe`` header ``rosservice`` uses).
"""

from __future__ import annotations

import inspect
import logging
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import pydantic

from dataflow.transports import TransportError, load
from scart_ros1.msgs import MessageTypes, SrvType, UnknownTypeError
from scart_ros1.node import Node
from scart_ros1.services import ServiceError, ServiceServer, service_type

from .._rosplan import (Param, answering, is_model, match_params, operation_call, operation_signature,
                        resolve_converter, signature_of, type_label)
from .convert import _plain_value, field_conversion

if TYPE_CHECKING:
    from dataflow.task import TaskContext
    from scart_ros1.msgs import FieldDef

    from .transport import Ros1Transport

__all__ = ["Param", "ServedService", "ServiceProxy", "call_service", "check_service", "serve", "serve_operation"]

log = logging.getLogger(__name__)


def ros1_transport() -> Ros1Transport:
    """The process's ``ros1`` transport (the owner of its one node and message types).
    Raises :class:`TransportError` when the registered ``ros1`` plug-in is another one."""
    from .transport import Ros1Transport

    transport = load("ros1")
    if not isinstance(transport, Ros1Transport):
        raise TransportError(f"the registered 'ros1' transport is {type(transport).__qualname__}, "
                             "not scart's: its services cannot be served or called")
    return transport


# ---- planning ---------------------------------------------------------------------------
def _request_plan(types: MessageTypes, srv: SrvType, params: list[Param]) -> tuple[Callable[[object], list[object]], list[str]]:
    """``request -> positional arguments``, and the problems found."""
    by_name = {f.name: f for f in types.fields(srv.request.name)}
    pairs, problems = match_params(params, list(by_name), srv.request.name)
    if problems:
        return _no_args, problems
    convs = []
    for param, name in pairs:
        try:
            convs.append((name, field_conversion(types, param.type, by_name[name], outgoing=False)))
        except ValueError as exc:
            problems.append(f"parameter {param.name} ({type_label(param.type)}) vs {srv.request.name}.{name}: {exc}")
    plan = tuple(convs)
    return (lambda req: [conv(getattr(req, name)) for name, conv in plan]), problems


def _no_args(_request: object) -> list[object]:
    return []


def _response_plan(types: MessageTypes, srv: SrvType, returns: object) -> tuple[Callable[[object], object], bool, list[str]]:
    """``result -> response``, whether the response follows the success/message convention,
    and the problems found. ``returns``: the callable's return annotation (``Any``: none)."""
    resp = srv.response
    fields = types.fields(resp.name)
    names = {f.name: f for f in fields}
    convention = names.get("success", None) is not None and names["success"].type == "bool" and \
        names.get("message") is not None and names["message"].type == "string"
    new = resp.new
    if returns is type(None):
        return (lambda _r: new(success=True) if convention else new()), convention, []
    if returns is Any:
        return _dynamic_response(resp.cls, new, fields, convention), convention, []
    if convention and returns in (bool, str):
        return ((lambda r: new(success=bool(r))) if returns is bool
                else (lambda r: new(success=True, message=r))), True, []
    try:
        if is_model(returns):
            to_msg = field_conversion(types, returns, _message_field(resp.name), outgoing=True)
            return to_msg, convention, []
        if len(fields) == 1:
            conv, key = field_conversion(types, returns, fields[0], outgoing=True), fields[0].name
            return (lambda r: new(**{key: conv(r)})), convention, []
    except ValueError as exc:
        return _no_args, convention, [f"the return type {type_label(returns)} vs {resp.name}: {exc}"]
    return _no_args, convention, [f"the return type {type_label(returns)} fits no field of {resp.name} (fields: "
                                  f"{', '.join(names) or 'none'}): return a model with its fields, or give a converter"]


def _message_field(type_name: str) -> FieldDef:
    from scart_ros1.msgs import FieldDef

    return FieldDef("response", type_name)


def _dynamic_response(cls: type, new: Callable[..., object], fields: tuple, convention: bool) -> Callable[[object], object]:
    """For an unannotated callable: what it returned, judged at each call."""
    def to_response(result: object) -> object:
        if type(result) is cls:
            return result
        if result is None or (convention and result is True):
            return new(success=True) if convention else new()
        if isinstance(result, pydantic.BaseModel):
            return new(**result.model_dump())
        if isinstance(result, Mapping):
            return new(**result)
        if convention and isinstance(result, str):
            return new(success=True, message=result)
        if len(fields) == 1:
            return new(**{fields[0].name: result})
        raise TypeError(f"returned a {type(result).__name__}, which fits no field of {cls.__name__}")

    return to_response


def check_service(types: MessageTypes, type_name: str, params: list[Param], returns: object,
                  converter: str = "") -> list[str]:
    """What keeps a callable with ``params`` and ``returns`` from answering ``type_name``
    (``pkg/Srv``) requests (a composite's load-time check asks this)."""
    try:
        srv = types.srv(type_name)
    except UnknownTypeError as exc:
        return [str(exc)]
    if converter:
        try:
            fn = resolve_converter(converter)
            inspect.signature(fn).bind(None, None)
        except ValueError as exc:
            return [str(exc)]
        except TypeError:
            return [f"converter {converter} cannot be called as function(request, call)"]
        return []
    return _request_plan(types, srv, params)[1] + _response_plan(types, srv, returns)[2]


# ---- serving ----------------------------------------------------------------------------
class ServedService:
    """A ROS service answered by a callable (see the module docstring); :meth:`close`
    unadvertises it and lets the process's node go (idempotent). ``calls``/``failures``
    count what it answered."""

    def __init__(self, service: str, type_name: str, call: Callable[..., object], params: list[Param],
                 returns: object, *, converter: str = "", options: dict[str, str] | None = None,
                 label: str = "") -> None:
        self._transport = ros1_transport()
        self._transport.refuse_input(f"serving the ROS service {service}")
        types: MessageTypes = self._transport.types
        problems = check_service(types, type_name, params, returns, converter)
        if problems:
            raise TransportError(f"ROS service {service} ({type_name}) by {label or 'a callable'}: "
                                 + "; ".join(problems))
        srv = types.srv(type_name)
        self.label = label or getattr(call, "__qualname__", "a callable")
        self.calls = self.failures = 0
        self._closed = False
        if converter:
            fn = resolve_converter(converter)
            self._answer: Callable[[object], object] = lambda request: _response_of(srv, fn(request, call))
        else:
            args_of = _request_plan(types, srv, params)[0]
            response_of, convention = _response_plan(types, srv, returns)[:2]
            self._answer = answering(call, args_of, response_of, srv.response.new if convention else None)
        self._node = self._transport.acquire(options or {})
        try:
            self._server: ServiceServer = self._node.advertise_service(service, type_name, self._handle)
        except BaseException:
            self._transport.release(self._node)
            raise
        self.name = self._server.name

    def _handle(self, request: object) -> object:  # the node's service thread
        self.calls += 1
        try:
            return self._answer(request)
        except Exception:
            self.failures += 1
            raise

    @property
    def node(self) -> Node:
        return self._node

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._server.close()
        self._transport.release(self._node)


def _response_of(srv: SrvType, result: object) -> object:
    if type(result) is srv.response.cls:
        return result
    if isinstance(result, pydantic.BaseModel):
        result = result.model_dump()
    if isinstance(result, Mapping):
        return srv.response.new(**result)
    raise TypeError(f"the converter returned a {type(result).__name__}, not a {srv.response.name} or a mapping")


def serve(call: Callable[..., object], service: str, type_name: str, *, converter: str = "",
          options: dict[str, str] | None = None, label: str = "") -> ServedService:
    """Answer the ROS service ``service`` (``pkg/Srv``) with ``call``, whose parameters
    and return annotation say how requests and responses map. Raises
    :class:`TransportError` (types that do not map, no node)."""
    params, returns = signature_of(call)
    return ServedService(service, type_name, call, params, returns, converter=converter, options=options,
                         label=label)


def serve_operation(task: TaskContext, operation: str, service: str, type_name: str, *, converter: str = "",
                    options: dict[str, str] | None = None, timeout: float = 5.0) -> ServedService:
    """Answer the ROS service ``service`` with ``task``'s operation ``operation`` (its
    arguments checked as outside input; an answer within ``timeout`` s, else a service
    error). rtt_rosservice's ``connect("task.operation", "/service", "pkg/Srv")``."""
    params, returns = operation_signature(task, operation)
    call = operation_call(task, operation, timeout)
    return ServedService(service, type_name, call, params, returns, converter=converter, options=options,
                         label=f"{task.name}.{operation}")


# ---- calling ----------------------------------------------------------------------------
class ServiceProxy:
    """A ROS service called from scart: ``proxy(**fields)`` or ``proxy(request)`` (a
    mapping or model of the request's fields) returns the response as plain data (a
    mapping), or as ``returns`` (a pydantic model) when given. ``type_name`` None: asked of
    the service on the first call. Blocks ≤ ``timeout`` s per call; raises
    :class:`ServiceError` (no such service, its error, no answer) or ``TypeError`` for
    fields the request does not have. Thread-safe; :meth:`close` lets the node go."""

    def __init__(self, service: str, type_name: str | None = None, *, returns: type | None = None,
                 options: dict[str, str] | None = None, timeout: float = 5.0) -> None:
        self._transport = ros1_transport()
        self.type_name = type_name
        if type_name is not None:
            self._transport.types.srv(type_name)  # unknown: said now
        self.returns = returns
        self.timeout = timeout
        self._node: Node = self._transport.acquire(options or {})
        self.service = self._node.resolve(service)
        self._closed = False

    def __call__(self, request: Any = None, /, **fields: Any) -> Any:
        if self.type_name is None:
            self.type_name = service_type(self._node, self.service, self.timeout)
        srv = self._node.types.srv(self.type_name)
        if isinstance(request, pydantic.BaseModel):
            request = request.model_dump()
        given = {**(request or {}), **fields}
        reply = self._node.call_service(self.service, self.type_name, srv.request.new(**given), self.timeout)
        plain = _plain_value(reply)
        if self.returns is None:
            return plain
        from dataflow import registry

        return registry.validate(self.returns, plain)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._transport.release(self._node)

    def __enter__(self) -> ServiceProxy:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def call_service(service: str, request: object = None, *, type_name: str | None = None, timeout: float = 5.0,
                 options: dict[str, str] | None = None) -> object:
    """One call of the ROS service ``service`` (see :class:`ServiceProxy`); its response
    as plain data."""
    with ServiceProxy(service, type_name, options=options, timeout=timeout) as proxy:
        return proxy(request)
