"""What the ``ros1`` and ``ros2`` transports share: the rules on the Python side of a
conversion, which are the same whatever ROS's types are. Type inspection of a port's type
and of a converter's annotations (:func:`type_label`, :func:`check_converter`...),
converters found by name (:func:`resolve_converter`), a service's callable's parameters
matched to its request (:func:`signature_of`, :func:`match_params`, :func:`answering`),
and a stream's small pieces (:func:`flag`, :func:`receiver`, :class:`RefusingCarrier`).

One copy, so that the two transports keep one set of rules (their messages name the same
problems the same way). ROS-agnostic: it imports neither transport, nor rosbags nor
cyclonedds, and loading it stays as light as loading a transport.
"""

from __future__ import annotations

import inspect
import logging
import sys
import time
import types
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

import pydantic

from dataflow.transports import StreamProblem, TransportError

if TYPE_CHECKING:
    from dataflow.task import TaskContext
    from dataflow.transports.ends import ReaderEnd

__all__ = ["ConversionProblem", "Mismatch", "Param", "RefusingCarrier", "RosTime", "accepts", "answering", "check_converter",
           "flag", "is_mapping", "is_model", "is_open", "item_type", "latched", "match_params", "model_fields",
           "operation_call", "operation_signature", "receiver", "resolve_converter", "signature_of", "stamper",
           "stream_problems", "type_label",
           "unwrap", "usable"]

_C = TypeVar("_C")
_F = TypeVar("_F")
_Q = TypeVar("_Q")  #: a service's request
_R = TypeVar("_R")  #: a service's response
_M = TypeVar("_M")  #: a message as a subscription hands it over (an instance, or its bytes)
_TRUE, _FALSE = frozenset({"true", "1", "yes"}), frozenset({"false", "0", "no", ""})


class RosTime(Protocol):
    """A ROS 2 ``builtin_interfaces/Time`` as rosbags and Cyclone DDS give it."""

    sec: int
    nanosec: int


# ---- port types and annotations ------------------------------------------------------
@dataclass(frozen=True)
class ConversionProblem:
    """Why a port's type and a ROS type do not convert (``warning``: it may, unchecked)."""

    message: str
    warning: bool = False


class Mismatch(Exception):
    """A planning problem (collected as a :class:`ConversionProblem`)."""


def type_label(py_type: object) -> str:
    """A short name of a port type for messages (``float``, ``list[float]``, ``YouBotStatus``)."""
    return py_type.__name__ if isinstance(py_type, type) else str(py_type).replace("typing.", "")


def is_open(annotation: object) -> bool:
    """``annotation`` says nothing of the type (``Any``, ``object``)."""
    return annotation is Any or annotation is object


def is_mapping(annotation: object) -> bool:
    """``annotation`` is a mapping type (``dict``, ``Mapping[str, X]``...)."""
    origin = typing.get_origin(annotation) or annotation
    return isinstance(origin, type) and issubclass(origin, Mapping)


def is_model(py_type: object) -> bool:
    """``py_type`` is a pydantic model (converted by field names)."""
    return isinstance(py_type, type) and issubclass(py_type, pydantic.BaseModel)


def accepts(wanted: object, given: object) -> bool:
    """A parameter annotated ``wanted`` takes a value of type ``given``."""
    if is_open(wanted) or wanted == given:
        return True
    if wanted is float and given is int:
        return True
    return isinstance(wanted, type) and isinstance(given, type) and issubclass(given, wanted)


def unwrap(py_type: object) -> object:
    """``X`` for ``Optional[X]`` / ``X | None`` and ``Annotated[X, ...]``."""
    origin = typing.get_origin(py_type)
    if origin is typing.Annotated:
        return unwrap(typing.get_args(py_type)[0])
    if origin in (typing.Union, types.UnionType):
        rest = [a for a in typing.get_args(py_type) if a is not type(None)]
        if len(rest) == 1:
            return unwrap(rest[0])
    return py_type


def item_type(py_type: object) -> object | None:
    """The item type of ``list[X]`` / ``tuple[X, ...]`` / ``Sequence[X]``, else None."""
    origin, args = typing.get_origin(py_type), typing.get_args(py_type)
    if origin in (list, tuple) or (isinstance(origin, type) and origin.__name__ == "Sequence"):
        if origin is tuple and not (len(args) == 2 and args[1] is Ellipsis):
            return None
        return args[0] if args else Any
    return None


def model_fields(model: type[pydantic.BaseModel], ros_type: str, fields: Mapping[str, _F], outgoing: bool,
                 convert: Callable[[object, _F], Callable[[object], object]]) -> dict[str, Callable[[object], object]]:
    """The conversion of each field of ``model`` to or from its namesake of ``fields``
    (``ros_type``'s), made by ``convert(annotation, field)``. Publishing, every field of the
    model needs one; reading, every field it requires. Raises :class:`Mismatch` naming
    every problem, so that a model is fixed in one go."""
    convs: dict[str, Callable[[object], object]] = {}
    problems, missing = [], []
    for name, info in model.model_fields.items():
        field = fields.get(name)
        if field is None:
            if outgoing or info.is_required():
                missing.append(name)
            continue
        try:
            convs[name] = convert(unwrap(info.annotation), field)
        except Mismatch as exc:
            problems.append(f"{model.__name__}.{name} vs {ros_type}.{name}: {exc}")
    if missing:
        problems.insert(0, f"{model.__name__}'s {', '.join(missing)} {'has' if len(missing) == 1 else 'have'} "
                           f"no field in {ros_type} (its fields: {', '.join(fields) or 'none'})")
    if problems:
        raise Mismatch("; ".join(problems) + "; give a converter")
    return convs


# ---- converters -----------------------------------------------------------------------
def resolve_converter(ref: str) -> Callable[..., object]:
    """The function ``module:qualified.name`` of a module this process has imported
    already; raises ``ValueError`` saying what is wrong (never imports anything)."""
    module_name, colon, attr = ref.partition(":")
    if not colon or not module_name or not attr:
        raise ValueError(f"converter {ref!r}: expected module:function")
    module = sys.modules.get(module_name)
    if module is None:
        raise ValueError(f"converter {ref!r}: module {module_name!r} is not imported in this process (a stream "
                         "never imports code: import it first; a composite imports its converters at load)")
    obj: object = module
    for part in attr.split("."):
        obj = getattr(obj, part, None)
        if obj is None:
            raise ValueError(f"converter {ref!r}: module {module_name} has no {attr!r}")
    if not callable(obj):
        raise ValueError(f"converter {ref!r} is a {type(obj).__name__}, not a function")
    return obj


def check_converter(fn: Callable[..., object], ref: str, py_type: object, ros_type: str, outgoing: bool,
                    is_message: Callable[[object], bool]) -> list[ConversionProblem]:
    """The converter ``fn`` takes one argument, and its annotations, where given, fit the
    port's type and the message type (``is_message``: an annotation is ``ros_type``'s
    class). Checked when a stream is planned, so that a wrong converter is said then."""
    try:
        sig = inspect.signature(fn)
        sig.bind(None)
    except (TypeError, ValueError):
        return [ConversionProblem(f"converter {ref} cannot be called with one argument (the "
                                  f"{'value' if outgoing else 'message'})")]
    try:
        hints = typing.get_type_hints(fn)
    except Exception:  # noqa: BLE001 - unresolvable annotations: as if there were none
        hints = {}
    first = next(iter(sig.parameters.values()))
    given, returned = hints.get(first.name), hints.get("return")
    port = type_label(py_type)
    if outgoing:
        if given is not None and not accepts(given, py_type):
            return [ConversionProblem(f"converter {ref} takes {type_label(given)}; the port gives {port}")]
        if returned is not None and not (is_open(returned) or is_mapping(returned) or is_message(returned)):
            return [ConversionProblem(f"converter {ref} returns {type_label(returned)}; a {ros_type} (or a mapping "
                                      "of its fields) is needed")]
    else:
        if given is not None and not (is_open(given) or is_message(given)):
            return [ConversionProblem(f"converter {ref} takes {type_label(given)}; the topic gives {ros_type} messages")]
        if returned is not None and not (is_open(returned) or (is_mapping(returned) and is_model(py_type))
                                         or accepts(py_type, returned)):
            return [ConversionProblem(f"converter {ref} returns {type_label(returned)}; the port takes {port}")]
    if given is None and returned is None:
        return [ConversionProblem(f"converter {ref} has no type annotations: its types are checked only per "
                                  "sample", warning=True)]
    return []


# ---- services ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Param:
    """One parameter of a callable a service calls: its name and type (``Any``: unannotated)."""

    name: str
    type: object = Any


def signature_of(call: Callable[..., object], skip_self: bool = False) -> tuple[list[Param], object]:
    """The parameters and return annotation of ``call`` (``Any`` where unannotated);
    ``skip_self``: a function as declared on its class (its first parameter is ``self``)."""
    try:
        hints = typing.get_type_hints(call)
    except Exception:  # noqa: BLE001 - unresolvable annotations: as if there were none
        hints = {}
    sig = inspect.signature(call)
    params = [Param(p.name, hints.get(p.name, Any)) for p in sig.parameters.values()
              if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    if skip_self and params:
        params = params[1:]
    returns = hints.get("return", Any) if sig.return_annotation is not inspect.Parameter.empty else Any
    return params, type(None) if returns is None else returns


def operation_signature(task: TaskContext, operation: str) -> tuple[list[Param], object]:
    """The parameters and return type of ``task``'s operation, from its description."""
    from dataflow import registry

    desc = task.operations().get(operation)
    if desc is None:
        raise TransportError(f"task {task.name} has no operation {operation!r}; operations: "
                             f"{', '.join(sorted(task.operations())) or 'none'}")

    def of(name: str) -> object:
        return Any if name == "any" else type(None) if name == "None" else (registry.python_type(name) or Any)

    return [Param(n, of(t)) for n, t in desc.params], of(desc.returns)


def operation_call(task: TaskContext, operation: str, timeout: float) -> Callable[..., object]:
    """A callable that runs ``task``'s operation: its arguments checked as outside input
    (bounds, finiteness), its result waited for ≤ ``timeout`` s."""
    def call(*args: object) -> object:
        checked = task.check_arguments(operation, list(args))
        return task.send(operation, *checked).result(timeout)

    return call


def match_params(params: list[Param], fields: list[str], request: str) -> tuple[list[tuple[Param, str]], list[str]]:
    """The request field (of ``fields``, ``request``'s) each parameter takes, by name — a
    one-field request and a one-parameter callable pair up whatever their names — and the
    problems found (then no pairs)."""
    if len(params) == 1 and len(fields) == 1:
        return [(params[0], fields[0])], []
    known, wanted = set(fields), {p.name for p in params}
    missing = [p.name for p in params if p.name not in known]
    unused = [f for f in fields if f not in wanted]
    problems = ([f"parameter(s) {', '.join(missing)} have no field in {request} (fields: "
                 f"{', '.join(fields) or 'none'})"] if missing else []) + \
               ([f"{request} field(s) {', '.join(unused)} match no parameter "
                 f"({', '.join(p.name for p in params) or 'none'})"] if unused else [])
    if problems:
        return [], problems
    return [(p, p.name) for p in params], []


def answering(call: Callable[..., object], args_of: Callable[[_Q], list[object]], response_of: Callable[[object], _R],
              convention: Callable[..., _R] | None) -> Callable[[_Q], _R]:
    """``request -> response`` of a served callable. ``convention``, for a response with
    ``bool success`` and ``string message``, makes a response from those fields: then
    ``False`` or an exception answers ``success: false`` (with its text); without it an
    exception goes to the caller."""
    def answer(request: _Q) -> _R:
        args = args_of(request)
        if convention is None:
            return response_of(call(*args))
        try:
            result = call(*args)
        except Exception as exc:  # noqa: BLE001 - success/message: the failure is the answer
            return convention(success=False, message=f"{type(exc).__name__}: {exc}"[:1000])
        if result is False:
            return convention(success=False)
        return response_of(result)

    return answer


# ---- streams ----------------------------------------------------------------------------
def flag(options: Mapping[str, str], key: str) -> bool:
    """The boolean option ``key`` (absent: False); raises ``ValueError`` for another word."""
    value = options.get(key, "").strip().lower()
    if value in _TRUE:
        return True
    if value in _FALSE:
        return False
    raise ValueError(f"option {key}={options[key]!r}: expected true or false")


def latched(options: Mapping[str, str], policy: Any) -> bool:
    """Whether a ROS stream's publisher latches (ROS 1 latch, ROS 2 transient-local): only
    when asked, as in ROS — the ``latch`` option, or a buffer policy given ``init`` (DATA's
    own ``init``, its default, is not asking: a restarting subscriber must not get a
    stale command)."""
    from dataflow.policy import ConnType

    if "latch" in options:
        return flag(options, "latch")
    return bool(policy is not None and policy.init and policy.type is not ConnType.DATA)


def stream_problems(transport: str, port: Any, problems: list[ConversionProblem]) -> list[StreamProblem]:
    """A stream's conversion problems as the stream problems ``scart validate`` shows,
    each naming the transport and the port."""
    where = f"{'into' if port.is_input else 'from'} port {getattr(port, 'qualname', port.name)} ({port.type_name})"
    return [StreamProblem(f"{transport} {where}: {p.message}", p.warning, types=True) for p in problems]


def usable(conv: _C | None, problems: list[StreamProblem], log: logging.Logger) -> _C:
    """The conversion a stream is made with: its warnings logged on ``log`` (the
    transport's), its errors raised as :class:`TransportError`."""
    for p in problems:
        if p.warning:
            log.warning("%s", p.message)
    if conv is None:
        raise TransportError("; ".join(p.message for p in problems if not p.warning))
    return conv


def receiver(end: ReaderEnd, convert: Callable[[_M], object], label: str) -> Callable[[_M], None]:
    """What a subscription calls with each message (one at a time): the value converted
    and handed to ``end``, numbered; a message that does not convert is refused there
    (``label``: its type), never ending the stream."""
    count = [0]

    def on_message(msg: _M) -> None:
        try:
            value = convert(msg)
        except Exception as exc:  # noqa: BLE001 - one bad message never ends the stream
            end.refuse(f"a {label} that does not convert: {type(exc).__name__}: {exc}")
            return
        count[0] += 1
        end.receive(count[0], time.time_ns(), value)

    return on_message


def stamper(port: object) -> Callable[[int], int]:
    """``wall_ns -> stamp``: what a ROS message's stamp is for a sample ``port`` wrote at
    ``wall_ns``, on its task's clock (a simulation's, with ``use_sim_time``), read at
    each sample (:mod:`dataflow.clock`)."""
    from dataflow.clock import WALL

    task = getattr(port, "task", None)
    if task is None:
        return WALL.stamp
    return lambda wall_ns: task.clock.stamp(wall_ns)


class RefusingCarrier:
    """The refusal count of a writer end's carrier: ``refused`` samples, the last one's
    ``refusal`` (the first is logged on the transport's ``log``)."""

    def __init__(self, label: str, log: logging.Logger) -> None:
        self._label = label
        self._log = log
        self.refused = 0
        self.refusal = ""

    def _refuse(self, why: str) -> None:
        self.refused += 1
        self.refusal = why[:300]
        if self.refused == 1:
            self._log.warning("%s: a sample refused: %s", self._label, self.refusal)
