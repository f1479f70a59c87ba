"""A bridge's types: what each input's source gives, what its converter takes and gives,
what the builder takes and returns, checked against each other and against the topics of
its streams (:class:`Resolver`), and the comparisons they use (:func:`same_type`,
:func:`path_type`)."""

from __future__ import annotations

import collections.abc
import inspect
import json
import types
import typing
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import pydantic

from dataflow import InputPort, OutputPort, registry
from dataflow.fields import apply_path
from scart.errors import Severity
from scart.bindings.dataflow._host import TASK_KIND, remote_ports
from scart.bindings.dataflow.settings import DataflowSettings
from scart.spi import AssemblyView, Location, Settings

from ._spec import BRIDGE, BRIDGE_TYPE, BridgeSpec, InputSpec, TopicSpec

__all__ = ["Resolved", "Resolver", "UNKNOWN", "path_type", "same_type", "shown"]

_UNKNOWN = None  # a type not known at load time (checked at start)
UNKNOWN = _UNKNOWN

def _plain(tp: object) -> object:
    """``T | None`` → ``T``; ``Any``/missing → unknown."""
    if tp in (None, inspect.Parameter.empty, typing.Any, object):
        return _UNKNOWN
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        args = [t for t in typing.get_args(tp) if t is not type(None)]
        return _plain(args[0]) if len(args) == 1 else _UNKNOWN
    return tp


def shown(tp: object) -> str:
    """A type as a message shows it."""
    if tp is _UNKNOWN:
        return "unknown"
    if isinstance(tp, type) and typing.get_origin(tp) is None:
        return tp.__name__
    return str(tp).replace("typing.", "")


def same_type(given: object, wanted: object) -> bool:
    """Can values of ``given`` stand where ``wanted`` is declared? Unknown is compatible; an
    int may stand for a float, a subclass for its base; a bare ``list``/``dict`` (or an
    abstract collection) accepts any items; containers compare their item types pairwise.
    Types that came over the wire by name are the registry's classes, so identity holds."""
    given, wanted = _plain(given), _plain(wanted)
    if given is _UNKNOWN or wanted is _UNKNOWN or given == wanted:
        return True
    if given is int and wanted is float:
        return True
    g_origin, w_origin = typing.get_origin(given) or given, typing.get_origin(wanted) or wanted
    g_args, w_args = typing.get_args(given), typing.get_args(wanted)
    if not g_args and not w_args:  # two plain classes (bool is not a number here, as on the wire)
        return isinstance(given, type) and isinstance(wanted, type) and issubclass(given, wanted) and given is not bool
    sequences = (list, tuple, collections.abc.Sequence)
    if g_origin in sequences and w_origin in sequences:
        same_shape = True
    else:
        try:
            same_shape = isinstance(g_origin, type) and isinstance(w_origin, type) and issubclass(g_origin, w_origin)
        except TypeError:
            same_shape = False
    if not same_shape:
        return False
    if not g_args or not w_args:
        return True  # an unparameterised side: any items
    g_items, w_items = [a for a in g_args if a is not Ellipsis], [a for a in w_args if a is not Ellipsis]
    if Ellipsis in g_args or Ellipsis in w_args or g_origin is list or w_origin is list:
        return all(same_type(g, w) for g in g_items for w in w_items)  # homogeneous items
    return len(g_items) == len(w_items) and all(same_type(g, w) for g, w in zip(g_items, w_items))


def path_type(tp: object, path: tuple[str | int, ...]) -> tuple[object, str | None]:
    """The type a field path yields from a value of ``tp`` and why it cannot apply (None when
    it does). Unknown types stay unknown."""
    mapped = 0
    for step in path:
        tp = _plain(tp)
        if tp is _UNKNOWN:
            return _UNKNOWN, None
        if isinstance(step, str):
            fields = getattr(tp, "model_fields", None)
            if fields is None:
                if tp is dict or typing.get_origin(tp) is dict:
                    args = typing.get_args(tp)
                    tp = args[1] if len(args) == 2 else _UNKNOWN
                    continue
                return _UNKNOWN, f"{shown(tp)} has no field {step!r}"
            if step not in fields:
                return _UNKNOWN, f"{shown(tp)} has no field {step!r}; fields: {', '.join(fields)}"
            tp = fields[step].annotation
        else:
            if typing.get_origin(tp) not in (list, tuple):
                return _UNKNOWN, f"{shown(tp)} is not a list: [{'*' if step < 0 else step}] cannot apply"
            items = [t for t in typing.get_args(tp) if t is not Ellipsis]
            tp = items[0] if len(set(items)) == 1 else _UNKNOWN
            mapped += step < 0
    for _ in range(mapped):
        tp = types.GenericAlias(list, (tp,)) if tp is not _UNKNOWN else _UNKNOWN  # list[tp]
    return tp, None


def _hints(fn: Callable[..., object]) -> tuple[list[inspect.Parameter], dict[str, object]]:
    try:
        hints = typing.get_type_hints(fn)
    except Exception:  # noqa: BLE001 - unresolvable annotations: unchecked
        hints = {}
    try:
        params = list(inspect.signature(fn).parameters.values())
    except (TypeError, ValueError):
        params = []
    return params, hints


@dataclass
class Resolved:
    """A bridge with its types and callables: what a :class:`BridgeTask` is made from."""

    spec: BridgeSpec
    sources: dict[str, object]  # input -> source port type (unknown: None)
    converters: dict[str, Callable[[object], object] | None]
    converted: dict[str, object]  # input -> converted type
    defaults: dict[str, object]
    output_type: object
    build: Callable[..., object]
    local: set[str] = field(default_factory=set)  # inputs whose source is a task of this runtime


class Resolver:
    """Resolves bridges against an assembly: each problem is ``(code, message, where,
    severity)``, ``where`` the ``<scart:input>`` it is about (None: the bridge itself)."""

    def __init__(self, assembly: AssemblyView, settings: Settings, importer: Callable[[str], object],
                 bridges: dict[str, BridgeSpec]) -> None:
        self.assembly = assembly
        self.settings = settings
        self.importer = importer
        self.bridges = bridges
        self.problems: list[tuple[str, str, Location | None, Severity]] = []
        self._resolved: dict[str, Resolved | None] = {}
        self._at: Location | None = None  # the input being resolved

    def problem(self, code: str, message: str, severity: Severity = "error") -> None:
        self.problems.append((code, message, self._at, severity))

    def errors(self) -> int:
        """How many problems are errors (warnings do not keep a bridge from running)."""
        return sum(1 for p in self.problems if p[3] == "error")

    def _import(self, ref: str, what: str) -> object:
        try:
            return self.importer(ref)
        except Exception as exc:  # noqa: BLE001 - any import failure is the composite's problem
            self.problem(BRIDGE, f"{what}: cannot import {ref!r}: {type(exc).__name__}: {exc}")
            return None

    def output_type(self, spec: BridgeSpec) -> object:
        """The output's Python type (``mod:Class``, or a registry name); None (reported) if unknown."""
        tp = self._type(spec.output_type, f"bridge {spec.name!r} output {spec.output!r}")
        if tp is not None and spec.output_topic is not None:
            self.topic(spec.output_topic, OutputPort(tp, spec.output), f"bridge {spec.name!r} output {spec.output!r}")
        return tp

    def _type(self, ref: str, what: str) -> object:
        if ":" in ref:
            return self._import(ref, f"{what} type")
        tp = registry.python_type(ref)
        if tp is None:
            self.problem(BRIDGE, f"{what}: type {ref!r} is neither mod:Class nor a registered type name")
        return tp

    def topic(self, topic: TopicSpec, port: InputPort[object] | OutputPort[object], what: str) -> None:
        """What keeps the bridge's ``port`` from joining ``topic`` (said at the stream's line)."""
        from dataflow.transports import TransportError, load

        outer, self._at = self._at, topic.loc
        try:
            found = load(topic.transport).check_stream(port, topic.topic, dict(topic.options))
        except TransportError as exc:
            self.problem(BRIDGE, f"{what}: {exc}")
            found = []
        for p in found:
            self.problem(BRIDGE_TYPE if p.types else BRIDGE, f"{what} <scart:stream {topic.where}>: {p.message}",
                         "warning" if p.warning else "error")
        self._at = outer

    def source_type(self, spec: BridgeSpec, inp: InputSpec, online: bool) -> tuple[object, bool]:
        """(the source port's type or unknown, whether the source runs in this runtime)."""
        self._at = inp.loc
        if inp.topic is not None:
            what = f"bridge {spec.name!r} input {inp.name!r}"
            tp = self._type(inp.declared or "", what)
            if tp is not None:
                self.topic(inp.topic, InputPort(tp, inp.name), what)
            return (tp if tp is not None else _UNKNOWN), True
        comp, port = inp.source
        where = f"bridge {spec.name!r} input {inp.name!r}: {comp}.{port}"
        node = self.assembly.nodes.get(comp)
        if node is not None:
            if node.kind != TASK_KIND:
                self.problem(BRIDGE, f"{where}: component {comp!r} is not an implementation.task")
                return _UNKNOWN, True
            ports = {p.name: p for p in getattr(node.ctype.cls, "_port_templates", {}).values()}
            found = ports.get(port)
            if found is None or found.is_input:
                self.problem(BRIDGE, f"{where}: task {comp!r} has no output port {port!r}; outputs: "
                             f"{', '.join(n for n, p in ports.items() if not p.is_input) or 'none'}")
                return _UNKNOWN, True
            return found.type, True
        if comp in self.bridges:
            other = self.bridges[comp]
            if port != other.output:
                self.problem(BRIDGE, f"{where}: bridge {comp!r} has one output, {other.output!r}")
                return _UNKNOWN, True
            resolved = self.resolve(other, online) if comp != spec.name else None
            self._at = inp.loc
            return (resolved.output_type if resolved is not None else _UNKNOWN), True
        if not online:
            return _UNKNOWN, False
        own = DataflowSettings.of(self.settings)
        ns = inp.ns or own.ns_address
        remote = remote_ports(ns, own.remap.component(comp), timeout=0.5, security=self.settings.security)
        if remote is None:
            return _UNKNOWN, False
        info = remote.get(own.remap.port(comp, port))
        if info is None or info.direction != "out":
            self.problem(BRIDGE, f"{where}: task {comp!r} (name service {ns}) has no output port {port!r}; "
                         f"outputs: {', '.join(p.name for p in remote.values() if p.direction == 'out') or 'none'}")
            return _UNKNOWN, False
        tp = registry.python_type(info.type_name)
        if tp is None:
            self.problem(BRIDGE, f"{where}: its type {info.type_name!r} is not registered in this process "
                         "(import the module defining it, e.g. in a converter's module)")
            return _UNKNOWN, False
        return tp, False

    def resolve(self, spec: BridgeSpec, online: bool | None = None) -> Resolved | None:
        """The bridge resolved (types checked); None when it cannot run (reported)."""
        if spec.name in self._resolved:
            return self._resolved[spec.name]
        self._resolved[spec.name] = None  # a cycle of bridges resolves as unknown
        online = self.settings.online if online is None else online
        before, outer = self.errors(), self._at
        self._at = None
        out_type = self.output_type(spec)
        sources: dict[str, object] = {}
        converters: dict[str, Callable[[object], object] | None] = {}
        converted: dict[str, object] = {}
        defaults: dict[str, object] = {}
        local: set[str] = set()
        for inp in spec.inputs:
            src, is_local = self.source_type(spec, inp, online)
            self._at = inp.loc  # after the source: another bridge resolved through it says its own
            sources[inp.name] = src
            if is_local:
                local.add(inp.name)
            converters[inp.name], converted[inp.name] = self.converter(spec, inp, src)
            if inp.missing == "default":
                defaults[inp.name] = self.default(spec, inp, converted[inp.name])
            self._at = None
        build = self.builder(spec, converted, out_type) if out_type is not None else None
        self._at = outer
        if self.errors() > before or build is None or out_type is None:
            return None
        resolved = Resolved(spec, sources, converters, converted, defaults, out_type, build, local)
        self._resolved[spec.name] = resolved
        return resolved

    def converter(self, spec: BridgeSpec, inp: InputSpec,
                  src: object) -> tuple[Callable[[object], object] | None, object]:
        where = f"bridge {spec.name!r} input {inp.name!r}"
        if inp.path is not None:
            path = inp.path
            if len(path) > 1 and path[0] == inp.name and path_type(src, path[:1])[1] is not None:
                path = path[1:]  # "arm.joints[*].position" on input arm: the input's own name leads
            tp, why = path_type(src, path)
            if why is not None:
                self.problem(BRIDGE_TYPE, f"{where}: field path on {inp.origin} ({shown(src)}): {why}")
            return (lambda value: apply_path(value, path)), tp
        if inp.convert is None:
            return None, src
        fn = self._import(inp.convert, f"{where} converter")
        if fn is None:
            return None, _UNKNOWN
        if not callable(fn):
            self.problem(BRIDGE, f"{where}: converter {inp.convert!r} is not callable")
            return None, _UNKNOWN
        params, hints = _hints(fn)
        required = [p for p in params if p.default is inspect.Parameter.empty
                    and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
        if not params or len(required) > 1:
            self.problem(BRIDGE, f"{where}: converter {inp.convert} must take one argument (the sample)")
            return None, _UNKNOWN
        wanted = hints.get(params[0].name, _UNKNOWN)
        unannotated = [w for w, n in (("parameter", params[0].name), ("return", "return")) if n not in hints]
        if unannotated:
            self.problem(BRIDGE, f"{where}: converter {inp.convert} has no type annotation on its "
                         f"{' and '.join(unannotated)}: what it is given and gives is not checked, and pydantic "
                         "coerces it silently where a type is declared (\"1.5\" becomes 1.5); annotate it",
                         severity="warning")
        if not same_type(src, wanted):
            self.problem(BRIDGE_TYPE, f"{where}: converter {inp.convert} takes {shown(_plain(wanted))}, but "
                         f"{inp.origin} is {shown(src)}")
        return fn, _plain(hints.get("return", _UNKNOWN))

    def default(self, spec: BridgeSpec, inp: InputSpec, tp: Any) -> object:  # Any: a type expression for pydantic
        raw = inp.default or ""
        try:
            data = json.loads(raw)
        except json.JSONDecodeError:
            data = raw
        if tp is _UNKNOWN:
            return data
        try:
            return pydantic.TypeAdapter(tp).validate_python(data)
        except pydantic.ValidationError as exc:
            why = exc.errors()[0]["msg"]
        except Exception as exc:  # noqa: BLE001 - a type pydantic cannot validate (a plain class)
            why = f"{shown(tp)} values cannot be read from text ({type(exc).__name__})"
        self.problem(BRIDGE_TYPE, f"bridge {spec.name!r} input {inp.name!r}: default {raw!r:.60} is not a "
                     f"{shown(tp)}: {why}")
        return None

    def builder(self, spec: BridgeSpec, converted: dict[str, object], out_type: object) -> Callable[..., object] | None:
        where = f"bridge {spec.name!r} output {spec.output!r}"
        if spec.build is not None:
            fn = self._import(spec.build, f"{where} builder")
            if fn is None or not callable(fn):
                if fn is not None:
                    self.problem(BRIDGE, f"{where}: builder {spec.build!r} is not callable")
                return None
            params, hints = _hints(fn)
            names = {p.name: p for p in params if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)}
            takes_all = any(p.kind is p.VAR_KEYWORD for p in params)
            for name, tp in converted.items():
                if name not in names:
                    if not takes_all:
                        self.problem(BRIDGE, f"{where}: builder {spec.build} has no parameter {name!r} for input "
                                     f"{name!r}; its parameters: {', '.join(names) or 'none'}")
                    continue
                if not same_type(tp, hints.get(name, _UNKNOWN)):
                    self.problem(BRIDGE_TYPE, f"{where}: builder {spec.build} parameter {name!r} is "
                                 f"{shown(_plain(hints.get(name)))}, but input {name!r} gives {shown(tp)}")
            for name, p in names.items():
                if name not in converted and p.default is inspect.Parameter.empty:
                    self.problem(BRIDGE, f"{where}: builder {spec.build} parameter {name!r} is no input; inputs: "
                                 f"{', '.join(converted)}")
            returns = hints.get("return", _UNKNOWN)
            if not same_type(returns, out_type):
                self.problem(BRIDGE_TYPE, f"{where}: builder {spec.build} returns {shown(_plain(returns))}, but the "
                             f"output is {shown(out_type)}")
            return typing.cast(Callable[..., object], fn)
        fields = getattr(out_type, "model_fields", None)
        if fields is None:
            self.problem(BRIDGE, f"{where}: type {shown(out_type)} is not a pydantic model: give build=\"mod:function\"")
            return None
        for name, tp in converted.items():
            if name not in fields:
                self.problem(BRIDGE, f"{where}: {shown(out_type)} has no field {name!r} for input {name!r}; fields: "
                             f"{', '.join(fields)}")
            elif not same_type(tp, fields[name].annotation):
                self.problem(BRIDGE_TYPE, f"{where}: {shown(out_type)}.{name} is {shown(_plain(fields[name].annotation))}"
                             f", but input {name!r} gives {shown(tp)}")
        lacking = [n for n, f in fields.items() if f.is_required() and n not in converted]
        if lacking:
            self.problem(BRIDGE, f"{where}: {shown(out_type)} needs field(s) {', '.join(lacking)} no input gives")
        return typing.cast(Callable[..., object], out_type)




