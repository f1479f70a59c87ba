"""ROS 2 services and scart, both ways, through this process's participant (the ``ros2``
transport's, see :mod:`._transport`), with the ``ros1`` transport's rules
(:mod:`dataflow.transports.ros1.calls`) on ROS 2's types.

**A ROS 2 service answered by scart** (:func:`serve`, :func:`serve_operation`): a callable
— a task's operation (rtt_ros2's ``connect("task.operation", "/service", "pkg/srv/Srv")``)
— answers ``pkg/srv/Srv`` requests. Request fields become the callable's arguments **by
name** (a one-field request and a one-parameter callable pair up whatever their names); the
return value becomes the response: a model by field names, a plain value into a one-field
response, ``None`` as the response's zero. A response with ``bool success`` and ``string
message`` (``std_srvs/srv/Trigger``, ``SetBool``) follows their convention: ``None`` or
``True`` is success, a string is the message, ``False`` or an exception is ``success:
false`` with its text. Otherwise an exception sends no reply (ROS 2 has no error reply:
the caller times out) and is counted. Types are checked when the service is made; a
task's arguments are checked as any outside input (bounds, finiteness) before the
operation runs, which must answer within ``timeout`` s. The answer is computed on the
participant's thread: keep operations short (their samples wait meanwhile).

**A ROS 2 service called from scart**: :class:`ServiceProxy` (``proxy(**fields)`` returns
the response as plain data, or as a model it is given) and :func:`call_service`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import pydantic
from rosbags.typesys.base import Nodetype

from dataflow.transports import TransportError, load

from scart_ros2.errors import Ros2Error, UnknownTypeError
from scart_ros2.names import topic_name
from scart_ros2.msgs import MessageTypes, message_to_dict

from .._rosplan import (Mismatch, Param, answering, is_model, match_params, operation_call, operation_signature,
                        signature_of, type_label, unwrap)
from ._convert import _Planner

if TYPE_CHECKING:
    from dataflow.task import TaskContext

__all__ = ["Param", "ServedService", "ServiceProxy", "call_service", "check_service", "ros2_transport", "serve",
           "serve_operation"]

log = logging.getLogger(__name__)

_EMPTY = "structure_needs_at_least_one_member"  # rosidl's member of an empty struct: no argument


def ros2_transport() -> Any:
    """The process's ``ros2`` transport (scart's: a plug-in under that name is refused)."""
    transport = load("ros2")
    if not hasattr(transport, "acquire"):
        raise TransportError(f"transport 'ros2' is a {type(transport).__qualname__}, not scart's")
    return transport


# ---- planning ---------------------------------------------------------------------------
def _request_plan(types: MessageTypes, request: str, params: list[Param]
                  ) -> tuple[Callable[[object], list[object]], list[str]]:
    """``request -> positional arguments``, and the problems found."""
    by_name = {n: d for n, d in types.fields(request) if n != _EMPTY}
    pairs, problems = match_params(params, list(by_name), request)
    if problems:
        return _no_args, problems
    planner, convs = _Planner(types, outgoing=False), []
    for param, name in pairs:
        try:
            convs.append((name, planner.field(unwrap(param.type), by_name[name], 0)))
        except Mismatch as exc:
            problems.append(f"parameter {param.name} ({type_label(param.type)}) vs {request}.{name}: {exc}")
    plan = tuple(convs)
    return (lambda req: [conv(getattr(req, name)) for name, conv in plan]), problems


def _no_args(_request: object) -> list[object]:
    return []


def _response_plan(types: MessageTypes, response: str, returns: Any
                   ) -> tuple[Callable[[Any], dict[str, Any]], bool, list[str]]:
    """``result -> the response's fields``, whether the response follows the
    success/message convention, and the problems found (``returns``: ``Any`` when the
    callable says nothing)."""
    fields = [(n, d) for n, d in types.fields(response) if n != _EMPTY]
    names = dict(fields)
    convention = names.get("success") == (Nodetype.BASE, ("bool", 0)) and \
        names.get("message") == (Nodetype.BASE, ("string", 0))
    if returns is type(None):
        return (lambda _r: {"success": True} if convention else {}), convention, []
    if returns is Any:
        return _dynamic_response(fields, convention), convention, []
    if convention and returns in (bool, str):
        return ((lambda r: {"success": bool(r)}) if returns is bool
                else (lambda r: {"success": True, "message": r})), True, []
    planner = _Planner(types, outgoing=True)
    try:
        if is_model(returns):
            return planner.model(returns, response, 0), convention, []
        if len(fields) == 1:
            key, desc = fields[0]
            conv = planner.field(unwrap(returns), desc, 0)
            return (lambda r: {key: conv(r)}), convention, []
    except Mismatch as exc:
        return _nothing, convention, [f"the return type {type_label(returns)} vs {response}: {exc}"]
    return _nothing, convention, [f"the return type {type_label(returns)} fits no field of {response} (fields: "
                                  f"{', '.join(names) or 'none'}): return a model with its fields"]


def _nothing(_result: object) -> dict[str, object]:
    return {}


def _dynamic_response(fields: Sequence[tuple[str, object]], convention: bool) -> Callable[[object], dict[str, object]]:
    """For an unannotated callable: what it returned, judged at each call."""
    def to_response(result: object) -> dict[str, object]:
        if result is None or (convention and result is True):
            return {"success": True} if convention else {}
        if isinstance(result, pydantic.BaseModel):
            return result.model_dump()
        if isinstance(result, Mapping):
            return dict(result)
        if convention and isinstance(result, str):
            return {"success": True, "message": result}
        if len(fields) == 1:
            return {fields[0][0]: result}
        raise TypeError(f"returned a {type(result).__name__}, which fits no field of the response")

    return to_response


def check_service(types: MessageTypes, type_name: str, params: list[Param], returns: object) -> list[str]:
    """What keeps a callable with ``params`` and ``returns`` from answering ``type_name``
    (``pkg/srv/Srv``) requests."""
    try:
        request, response = types.service(type_name)
    except (UnknownTypeError, ValueError) as exc:
        return [str(exc)]
    return _request_plan(types, request, params)[1] + _response_plan(types, response, returns)[2]


# ---- serving ----------------------------------------------------------------------------
class ServedService:
    """A ROS 2 service answered by a callable (see the module docstring); :meth:`close`
    withdraws it and lets the process's participant go (idempotent). ``calls`` and
    ``failures`` count what it answered."""

    def __init__(self, service: str, type_name: str, call: Callable[..., Any], params: list[Param], returns: Any,
                 *, options: Mapping[str, str] | None = None, label: str = "") -> None:
        self._transport = ros2_transport()
        self._transport.refuse_input(f"serving the ROS 2 service {service}")
        types: MessageTypes = self._transport.types
        self.label = label or getattr(call, "__qualname__", "a callable")
        problems = check_service(types, type_name, params, returns)
        try:
            self.name = self._transport.remapped(service)
            where = self._transport.where(options or {})
        except ValueError as exc:
            problems.append(str(exc))
        if problems:
            raise TransportError(f"ROS 2 service {service} ({type_name}) by {self.label}: " + "; ".join(problems))
        request, response = types.service(type_name)
        args_of = _request_plan(types, request, params)[0]
        response_of, convention = _response_plan(types, response, returns)[:2]
        self._answer = answering(call, args_of, response_of, dict if convention else None)
        self.calls = self.failures = 0
        self._closed = False
        self._participant = self._transport.acquire(where)
        try:
            self._server = self._participant.service(self.name, type_name, self._handle, raw=True)
        except BaseException:
            self._transport.release(self._participant)
            raise

    def _handle(self, request: object) -> object:  # the participant's thread
        self.calls += 1
        try:
            return self._answer(request)
        except Exception:
            self.failures += 1
            raise

    @property
    def refused(self) -> int:
        """Requests not answered (the callable raised, or the reply could not be made)."""
        return self._server.refused

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._server.close()
        self._transport.release(self._participant)

    def __enter__(self) -> ServedService:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def serve(call: Callable[..., object], service: str, type_name: str, *,
          options: Mapping[str, str] | None = None, label: str = "") -> ServedService:
    """Answer the ROS 2 service ``service`` (``pkg/srv/Srv``) with ``call``, whose
    parameters and return annotation say how requests and responses map (``label``: what
    answers, in messages). Raises :class:`TransportError` (types that do not map, a bad
    name, no participant)."""
    params, returns = signature_of(call)
    return ServedService(service, type_name, call, params, returns, options=options, label=label)


def serve_operation(task: TaskContext, operation: str, service: str, type_name: str, *,
                    options: Mapping[str, str] | None = None, timeout: float = 5.0) -> ServedService:
    """Answer the ROS 2 service ``service`` with ``task``'s operation ``operation`` (its
    arguments checked as outside input; an answer within ``timeout`` s, else no reply)."""
    params, returns = operation_signature(task, operation)
    call = operation_call(task, operation, timeout)
    return ServedService(service, type_name, call, params, returns, options=options,
                         label=f"{task.name}.{operation}")


# ---- calling ----------------------------------------------------------------------------
class ServiceProxy:
    """A ROS 2 service called from scart: ``proxy(**fields)`` or ``proxy(request)`` (a
    mapping or model of the request's fields) returns the response as plain data (a
    mapping), or as ``returns`` (a pydantic model) when given. Blocks ≤ ``timeout`` s per
    call (waiting for the service first); raises ``TimeoutError`` (no service, or no
    answer: ROS 2 has no error reply), :class:`~._errors.ConversionError` for fields the
    request does not have. Thread-safe; :meth:`close` lets the participant go."""

    def __init__(self, service: str, type_name: str, *, returns: type | None = None,
                 options: Mapping[str, str] | None = None, timeout: float = 5.0) -> None:
        self._transport = ros2_transport()
        self._transport.types.service(type_name)  # an unknown type: said now
        self.service, self.type_name = self._transport.remapped(service), type_name
        self.returns, self.timeout = returns, timeout
        self._participant = self._transport.acquire(self._transport.where(options or {}))
        try:
            self._client = self._participant.client(self.service, type_name)
        except BaseException:
            self._transport.release(self._participant)
            raise
        self._closed = False

    def __call__(self, request: Any = None, /, **fields: Any) -> Any:
        if self._closed:
            raise Ros2Error(f"the client of {self.service} is closed")
        if isinstance(request, pydantic.BaseModel):
            request = request.model_dump()
        given = {**(request or {}), **fields}
        if not self._client.wait_for_service(self.timeout):
            raise TimeoutError(f"ROS 2 service {self.service} ({self.type_name}) is not there "
                               f"within {self.timeout} s")
        plain = message_to_dict(self._client.call(given, self.timeout))
        plain.pop(_EMPTY, None)
        if self.returns is None:
            return plain
        from dataflow import registry

        return registry.validate(self.returns, plain)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._client.close()
            self._transport.release(self._participant)

    def __enter__(self) -> ServiceProxy:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def call_service(service: str, request: object = None, *, type_name: str, timeout: float = 5.0,
                 options: Mapping[str, str] | None = None) -> object:
    """One call of the ROS 2 service ``service`` of ``type_name`` (``pkg/srv/Srv``; see
    :class:`ServiceProxy`); its response as plain data."""
    with ServiceProxy(service, type_name, options=options, timeout=timeout) as proxy:
        return proxy(request)
