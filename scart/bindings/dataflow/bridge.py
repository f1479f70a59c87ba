"""``<scart:bridge>``: many ports → converters → one typed output, declared in the composite.

The hub / converters / output-builder shape of a generated middleware bridge, with no
generated code and with the types checked at load time::

    <scart:bridge name="statusBridge" trigger="periodic" period="0.01">
      <scart:input name="arm" from="youBotDriver.jointStatus" field="joints[*].position"/>
      <scart:input name="busy" from="locomotor.busy" missing="default" default="false"/>
      <scart:output name="summary" type="summary:ArmSummary" build="summary:make"/>
    </scart:bridge>

* **Inputs** — ``from`` is ``TASK.PORT``: a task of this composite, another bridge's
  output, or a task of another deployer found through the name service (``ns``, else the
  runtime's). ``policy`` is the connection's (``ConnPolicy.parse`` form, default
  ``data``). Each input is converted by a Python callable (``convert="mod:function"``,
  called with the sample), or by a field path (``field="joints[*].position"``: ``.name``
  a field or key, ``[N]`` an item, ``[*]`` every item; the input's own name may lead the
  path, as in ``arm.joints[*].position``), or not at all.
* **Output** — one port, ``name`` and ``type`` (``mod:Class``, or a registry name such as
  ``float64``). ``build="mod:function"`` is called with the converted inputs as keyword
  arguments (by input name); without it the type is a pydantic model whose fields are the
  inputs (by name).
* **Topics** — an input may be fed by a topic instead of a port, and the output may be
  written to one: a ``<scart:stream transport=".." topic=".." .../>`` inside the
  ``<scart:input>`` (which then takes a ``type`` and no ``from``) or the ``<scart:output>``,
  its other attributes the transport's options, as ``<scart:stream>``'s. So a bridge joins
  two middlewares by itself (a YARP port to a ROS topic: ``composites/yarp-ros/``), the
  port's type checked against each topic's at load.
* **Trigger** — ``periodic`` (every ``period`` s, the default when ``period`` is given),
  ``any`` (on any new input, the default otherwise) or ``all`` (when every input has a new
  sample and their arrival times lie within ``window`` s of each other, as
  message_filters' ApproximateTime; an older sample is dropped for a newer one). A
  ``period`` with ``any`` or ``all`` is refused (it would not apply).
* **Missing inputs** (``missing``, periodic and any-input triggers) — ``hold`` (default: the last value; no output until
  the first one), ``skip`` (no output unless this input has a new sample) or ``default``
  (the last value, and the ``default`` value, JSON, until the first sample).

**Type-checked at load time** (``file:line`` — the ``<scart:input>``'s for what concerns
one input — naming the input, the converter and both types): a converter's parameter
against its source port's type, a field path through the source's model, the builder's
parameters against the converted inputs and its return against the output type (or the
model's fields against them); a converter without type annotations is a warning. A
source of another deployer is checked when its name service answers at load time
(``settings.online``; one it does not know is then an error, and offline a warning), else
when the bridge starts: a mismatch then fails the start, naming the same things, and a
source not in the name service yet is waited for (the bridge starts when it appears).

It runs as a :class:`dataflow.TaskContext` (:class:`BridgeTask`) in the runtime's
deployer, named after the bridge, connected like ``scart:connect`` links, served and
registered like ``implementation.task`` components. ``scart describe NAME`` shows, for
each input, the age of its last sample (``INPUT.age``, seconds; null before the first)
and how many it got (``INPUT.samples``), and ``outputs``: how many were written.
"""

from __future__ import annotations

import collections.abc
import inspect
import json
import logging
import math
import threading
import time
import types
import typing
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import pydantic

from dataflow import (
    ConnPolicy, DataflowError, FlowStatus, InputPort, OutputPort, PeriodicActivity, TaskContext, registry,
)
from dataflow.fields import apply_path, parse_path
from dataflow.introspection import PropertyDescription, TaskDescription
from scart.errors import ScartError, Severity
from scart.bindings.dataflow._checks import remap_problems, remote_end
from scart.bindings.dataflow._host import TASK_KIND, Watcher, host_of, remote_ports
from scart.bindings.dataflow._plan import MIN_PERIOD_S
from scart.bindings.dataflow.tasks import ConnectParticipant, Link, connect_present, retire
from scart.bindings.dataflow.settings import DataflowSettings, Remap
from scart.spi import (
    AssemblyView, CheckContext, Element, ElementProvider, Host, Location, Participant, Problem, Settings,
)

log = logging.getLogger("scart.dataflow")

#: Problem codes of this module.
BRIDGE = "SCART-B001"  # a malformed bridge: attributes, inputs, output, trigger, a callable not found
BRIDGE_TYPE = "SCART-B002"  # types that do not agree: source, converter, builder, output

TRIGGERS = ("periodic", "any", "all")
MISSING = ("hold", "skip", "default")
MAX_INPUTS = 64
_UNKNOWN: Any = None  # a type not known at load time (checked at start)


# --- the element, read ------------------------------------------------------------------

@dataclass(frozen=True)
class TopicSpec:
    """A ``<scart:stream transport=".." topic=".."/>`` inside an input or the output: the
    bridge's own port joined to a topic of a transport (the other options the transport's)."""

    transport: str
    topic: str
    options: tuple[tuple[str, str], ...]
    loc: Location

    @property
    def where(self) -> str:
        return f"{self.transport}:{self.topic}"


@dataclass(frozen=True)
class InputSpec:
    """One ``<scart:input>``: fed by the port ``source``, or by the topic ``topic`` (then
    its type is ``declared``)."""

    name: str
    source: tuple[str, str]
    policy: ConnPolicy
    convert: str | None
    path: tuple[str | int, ...] | None  # field path steps: a name, an index, or -1 for [*]
    missing: str
    default: str | None
    ns: str | None
    where: str
    loc: Location | None = None  # the <scart:input>: where problems about this input are said
    topic: TopicSpec | None = None
    declared: str | None = None  # the type of a topic-fed input (mod:Class or a registry name)

    @property
    def origin(self) -> str:
        """What feeds it, as messages say: ``TASK.PORT`` or ``transport:topic``."""
        return self.topic.where if self.topic is not None else ".".join(self.source)


@dataclass(frozen=True)
class BridgeSpec:
    """One ``<scart:bridge>``, read (types not resolved yet)."""

    name: str
    trigger: str
    period: float | None
    window: float
    inputs: tuple[InputSpec, ...]
    output: str
    output_type: str
    build: str | None
    where: str
    output_topic: TopicSpec | None = None


def _split(ref: str) -> tuple[str, str] | None:
    comp, dot, port = ref.strip().rpartition(".")
    return (comp, port) if dot and comp and port else None


def parse_bridge(prefix: str, el: Element) -> tuple[BridgeSpec | None, list[tuple[str, str, Element]]]:
    """The bridge an element declares and the problems reading it (code, message, element)."""
    problems: list[tuple[str, str, Element]] = []
    a = el.attributes
    name = prefix + (a.get("name") or "").strip()
    what = f"<scart:bridge name={a.get('name', '')!r}>"

    def bad(message: str, at: Element = el) -> None:
        problems.append((BRIDGE, f"{what}: {message}", at))

    period = None
    if a.get("period") is not None:
        try:
            period = float(a["period"])
        except ValueError:
            period = math.nan
        if not (math.isfinite(period) and period >= MIN_PERIOD_S):
            bad(f"period {a['period']!r}: expected seconds ≥ {MIN_PERIOD_S}")
            period = None
    trigger = a.get("trigger") or ("periodic" if a.get("period") is not None else "any")
    if trigger not in TRIGGERS:
        bad(f"trigger {trigger!r}: expected one of {', '.join(TRIGGERS)}")
    elif trigger == "periodic" and period is None and a.get("period") is None:
        bad('trigger "periodic" needs a period (seconds)')
    elif trigger != "periodic" and a.get("period") is not None:  # it would be ignored: say so rather than guess
        bad(f'period {a["period"]!r} applies to trigger "periodic" only; trigger "{trigger}" outputs on new input '
            '(drop the period, or drop the trigger)')
    try:
        window = float(a.get("window", "0.05"))
    except ValueError:
        window = math.nan
    if not (math.isfinite(window) and 0 < window <= 3600):
        bad(f"window {a.get('window')!r}: expected seconds > 0")
        window = 0.05
    inputs: list[InputSpec] = []
    outputs = [c for c in el.children if c.kind == "output"]
    for child in el.children:
        if child.kind != "input":
            continue
        spec = _parse_input(prefix, child, bad, trigger)
        if spec is not None:
            if any(i.name == spec.name for i in inputs):
                bad(f"two inputs named {spec.name!r}", child)
            else:
                inputs.append(spec)
    if not inputs and not problems:
        bad("declares no <scart:input>")
    if len(inputs) > MAX_INPUTS:
        bad(f"{len(inputs)} inputs: at most {MAX_INPUTS}")
    if len(outputs) != 1:
        bad(f"needs exactly one <scart:output>, has {len(outputs)}")
        return None, problems
    out = outputs[0].attributes
    output, output_type = (out.get("name") or "").strip(), (out.get("type") or "").strip()
    if not output or not output_type:
        bad("<scart:output> needs a name and a type", outputs[0])
    elif not output.isidentifier():
        bad(f"<scart:output name={output!r}>: the name must be an identifier", outputs[0])
    if output in {i.name for i in inputs}:
        bad(f"the output and an input are both named {output!r}", outputs[0])
    output_topic = _topic(outputs[0], bad)
    if problems:
        return None, problems
    return BridgeSpec(name, trigger, period, window, tuple(inputs), output, output_type, out.get("build") or None,
                      str(el.loc), output_topic), problems


def _topic(el: Element, bad: Callable[[str, Element], None]) -> TopicSpec | None:
    """The ``<scart:stream>`` inside an input or output element, if any."""
    streams = [c for c in el.children if c.kind == "stream"]
    if not streams:
        return None
    if len(streams) > 1:
        bad(f"<scart:{el.kind}> holds {len(streams)} <scart:stream>: one at most", el)
        return None
    a = streams[0].attributes
    transport, topic = (a.get("transport") or "").strip(), (a.get("topic") or "").strip()
    if not transport or not topic:
        bad('<scart:stream> needs transport and topic (e.g. transport="yarp" topic="/robot/state")', streams[0])
        return None
    options = tuple(sorted((k, v) for k, v in a.items() if k not in ("transport", "topic") and ":" not in k))
    return TopicSpec(transport, topic, options, streams[0].loc)


def _parse_input(prefix: str, el: Element, bad: Callable[[str, Element], None], trigger: str) -> InputSpec | None:
    a = el.attributes
    name = (a.get("name") or "").strip()
    topic = _topic(el, bad)
    source = _split(a.get("from", "")) if topic is None else ("", "")
    if name and not name.isidentifier():
        bad(f"<scart:input name={name!r}>: the name must be an identifier (it is a keyword argument, a field, "
            "a port)", el)
        return None
    if topic is not None and (a.get("from") or not a.get("type")):
        bad(f"<scart:input name={name!r}> fed by a <scart:stream> takes a type (mod:Class or a registry name such "
            "as float64[]) and no from", el)
        return None
    if not name or source is None:
        bad(f"<scart:input name={name!r}> from={a.get('from', '')!r}: expected TASK.PORT (or a <scart:stream> "
            "inside, and a type)", el)
        return None
    try:
        policy = ConnPolicy.parse(a.get("policy", "data"))
    except ValueError as exc:
        bad(f"input {name!r}: {exc}", el)
        return None
    path = None
    if a.get("field") is not None:
        path = parse_path(a["field"])
        if path is None:
            bad(f"input {name!r}: field {a['field']!r} is not a path such as joints[*].position", el)
            return None
    if a.get("field") is not None and a.get("convert"):
        bad(f"input {name!r}: give convert or field, not both", el)
        return None
    missing = a.get("missing") or ("default" if a.get("default") is not None else "hold")
    if a.get("missing") is not None and trigger == "all":
        bad(f"input {name!r}: missing={a['missing']!r} does not apply to trigger \"all\" (it waits for every "
            "input)", el)
        return None
    if missing not in MISSING:
        bad(f"input {name!r}: missing={missing!r}: expected one of {', '.join(MISSING)}", el)
        return None
    if missing == "default" and a.get("default") is None:
        bad(f"input {name!r}: missing=\"default\" needs a default value", el)
        return None
    return InputSpec(name, (prefix + source[0], source[1]) if topic is None else source, policy,
                     a.get("convert") or None, path, missing, a.get("default"), a.get("ns") or None, str(el.loc),
                     el.loc, topic, a.get("type") or None)


# --- types ------------------------------------------------------------------------------

def _plain(tp: Any) -> Any:
    """``T | None`` → ``T``; ``Any``/missing → unknown."""
    if tp in (None, inspect.Parameter.empty, Any, object):
        return _UNKNOWN
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        args = [t for t in typing.get_args(tp) if t is not type(None)]
        return _plain(args[0]) if len(args) == 1 else _UNKNOWN
    return tp


def shown(tp: Any) -> str:
    """A type as a message shows it."""
    if tp is _UNKNOWN:
        return "unknown"
    if isinstance(tp, type) and typing.get_origin(tp) is None:
        return tp.__name__
    return str(tp).replace("typing.", "")


def same_type(given: Any, wanted: Any) -> bool:
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


def path_type(tp: Any, path: tuple[str | int, ...]) -> tuple[Any, str | None]:
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
        tp = list[tp] if tp is not _UNKNOWN else _UNKNOWN
    return tp, None


def _hints(fn: Callable[..., Any]) -> tuple[list[inspect.Parameter], dict[str, Any]]:
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
    sources: dict[str, Any]  # input -> source port type (unknown: None)
    converters: dict[str, Callable[[Any], Any] | None]
    converted: dict[str, Any]  # input -> converted type
    defaults: dict[str, Any]
    output_type: Any
    build: Callable[..., Any]
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

    def _import(self, ref: str, what: str) -> Any:
        try:
            return self.importer(ref)
        except Exception as exc:  # noqa: BLE001 - any import failure is the composite's problem
            self.problem(BRIDGE, f"{what}: cannot import {ref!r}: {type(exc).__name__}: {exc}")
            return None

    def output_type(self, spec: BridgeSpec) -> Any:
        """The output's Python type (``mod:Class``, or a registry name); None (reported) if unknown."""
        tp = self._type(spec.output_type, f"bridge {spec.name!r} output {spec.output!r}")
        if tp is not None and spec.output_topic is not None:
            self.topic(spec.output_topic, OutputPort(tp, spec.output), f"bridge {spec.name!r} output {spec.output!r}")
        return tp

    def _type(self, ref: str, what: str) -> Any:
        if ":" in ref:
            return self._import(ref, f"{what} type")
        tp = registry.python_type(ref)
        if tp is None:
            self.problem(BRIDGE, f"{what}: type {ref!r} is neither mod:Class nor a registered type name")
        return tp

    def topic(self, topic: TopicSpec, port: Any, what: str) -> None:
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

    def source_type(self, spec: BridgeSpec, inp: InputSpec, online: bool) -> tuple[Any, bool]:
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
        sources: dict[str, Any] = {}
        converters: dict[str, Callable[[Any], Any] | None] = {}
        converted: dict[str, Any] = {}
        defaults: dict[str, Any] = {}
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

    def converter(self, spec: BridgeSpec, inp: InputSpec, src: Any) -> tuple[Callable[[Any], Any] | None, Any]:
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

    def default(self, spec: BridgeSpec, inp: InputSpec, tp: Any) -> Any:
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

    def builder(self, spec: BridgeSpec, converted: dict[str, Any], out_type: Any) -> Callable[..., Any] | None:
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
            return typing.cast(Callable[..., Any], fn)
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
        return typing.cast(Callable[..., Any], out_type)


def bridges_of(elements: list[tuple[str, Element]]) -> dict[str, BridgeSpec]:
    """The well-formed bridges among ``elements``, by name."""
    return {spec.name: spec for prefix, el in elements if (spec := parse_bridge(prefix, el)[0]) is not None}


# --- the task ---------------------------------------------------------------------------

@dataclass
class _Input:
    port: InputPort[Any]
    value: Any = None  # the last sample accepted, converted
    has_value: bool = False
    fresh: bool = False  # a sample not yet used by an output
    arrived: float | None = None  # monotonic time of the last sample
    samples: int = 0


class BridgeTask(TaskContext):
    """The data-flow task a bridge runs as (see the module docstring)."""

    def __init__(self, resolved: Resolved, remap: Remap | None = None) -> None:
        spec = resolved.spec
        remap = remap or Remap()
        super().__init__(remap.component(spec.name))
        self.resolved = resolved
        event = spec.trigger in ("any", "all")
        self._inputs: dict[str, _Input] = {}
        for inp in spec.inputs:
            tp = resolved.sources[inp.name]
            origin = inp.origin if inp.topic is not None else ".".join(remap.endpoint(*inp.source))
            port: InputPort[Any] = InputPort(tp if tp is not None else object, remap.port(spec.name, inp.name),
                                             f"from {origin}", event=event)
            self._inputs[inp.name] = _Input(self.add_port(port))
        self.output: OutputPort[Any] = self.add_port(
            OutputPort(resolved.output_type, remap.port(spec.name, spec.output), f"built by bridge {self.name}"))
        self.outputs = 0
        self.errors = 0  # samples a converter or the builder refused (logged, then skipped)
        self._lock = threading.Lock()
        if spec.trigger == "periodic" and spec.period is not None:
            self.set_activity(PeriodicActivity(spec.period))

    def update_hook(self) -> None:
        now = time.monotonic()
        with self._lock:
            for name, state in self._inputs.items():
                status, value = state.port.read_newest()
                if status is not FlowStatus.NEW_DATA:
                    continue
                state.samples += 1
                convert = self.resolved.converters[name]
                try:  # converted once, on arrival: a refused sample is counted once and not held
                    value = convert(value) if convert is not None else value
                except Exception as exc:  # noqa: BLE001 - a converter refusing a sample
                    self._refused(f"converting input {name}", exc)
                    continue
                state.value, state.has_value, state.fresh, state.arrived = value, True, True, now
            values = self._sync() if self.resolved.spec.trigger == "all" else self._gather()
            if values is None:
                return
            for state in self._inputs.values():
                state.fresh = False
            try:
                self.output.write(self.resolved.build(**values))
            except Exception as exc:  # noqa: BLE001 - a builder refusing (or building the wrong type)
                self._refused(f"building {self.resolved.spec.output}", exc)
                return
            self.outputs += 1

    def _refused(self, what: str, exc: Exception) -> None:
        """Count a refused sample; log the first and every 1000th (one bad input must not flood)."""
        self.errors += 1
        if self.errors == 1 or self.errors % 1000 == 0:
            log.warning("bridge %s: %s failed (%d so far): %s: %s", self.name, what, self.errors,
                        type(exc).__name__, exc)

    def _gather(self) -> dict[str, Any] | None:
        """Periodic and any-input triggers: each input's value by its missing-input rule."""
        if not any(s.fresh for s in self._inputs.values()) and self.resolved.spec.trigger == "any":
            return None
        values: dict[str, Any] = {}
        for inp in self.resolved.spec.inputs:
            state = self._inputs[inp.name]
            if inp.missing == "default" and not state.has_value:
                values[inp.name] = self.resolved.defaults.get(inp.name)
            elif (inp.missing == "skip" and not state.fresh) or not state.has_value:
                return None
            else:
                values[inp.name] = state.value
        return values

    def _sync(self) -> dict[str, Any] | None:
        """All inputs fresh within the window (an older sample waits for a newer one)."""
        states = self._inputs.values()
        if not all(s.fresh for s in states):
            return None
        arrivals = [s.arrived or 0.0 for s in states]
        if max(arrivals) - min(arrivals) > self.resolved.spec.window:
            newest = max(arrivals)
            for s in states:  # too old for the newest: wait for its next sample
                if newest - (s.arrived or 0.0) > self.resolved.spec.window:
                    s.fresh = False
            return None
        return {name: s.value for name, s in self._inputs.items()}

    def ages(self) -> dict[str, float | None]:
        """Seconds since each input's last sample (None before the first)."""
        now = time.monotonic()
        return {n: (None if s.arrived is None else now - s.arrived) for n, s in self._inputs.items()}

    def describe(self) -> TaskDescription:
        """The task, with each input's age and sample count and the outputs written."""
        d = super().describe()
        extra = []
        for name, age in self.ages().items():
            extra.append(PropertyDescription(name=f"{name}.age", type_name="float64",
                                             value=None if age is None else round(age, 6),
                                             doc=f"seconds since input {name} got a sample (read-only)"))
            extra.append(PropertyDescription(name=f"{name}.samples", type_name="int64",
                                             value=self._inputs[name].samples,
                                             doc=f"samples input {name} got (read-only)"))
        extra.append(PropertyDescription(name="outputs", type_name="int64", value=self.outputs,
                                         doc=f"samples written to {self.resolved.spec.output} (read-only)"))
        extra.append(PropertyDescription(name="errors", type_name="int64", value=self.errors,
                                         doc="samples a converter or the builder refused (read-only)"))
        return d.model_copy(update={"properties": [*d.properties, *extra]})


# --- the element and its participant ---------------------------------------------------------

class BridgeElement(ElementProvider):
    """The ``scart:bridge`` composite element (see the module docstring)."""

    name = "bridge"

    def check(self, elements: list[tuple[str, Element]], assembly: AssemblyView,
              context: CheckContext) -> list[Problem]:
        """Static problems of every bridge element, at its line."""
        out: list[Problem] = []
        specs: dict[str, tuple[BridgeSpec, Element]] = {}
        for prefix, el in elements:
            spec, problems = parse_bridge(prefix, el)
            out += [Problem(code, msg, at.loc.path, at.loc.line) for code, msg, at in problems]
            if spec is None:
                continue
            if spec.name in specs or spec.name in assembly.nodes:
                out.append(Problem(BRIDGE, f"bridge {spec.name!r}: a component or bridge of that name exists",
                                   el.loc.path, el.loc.line))
                continue
            specs[spec.name] = (spec, el)
        resolver = Resolver(assembly, context.settings, context.import_object, {n: s for n, (s, _) in specs.items()})
        for spec, el in specs.values():
            out += _remote_inputs(spec, assembly, context, specs)
            before = len(resolver.problems)
            resolver.resolve(spec)
            out += [Problem(code, msg, (at or el.loc).path, (at or el.loc).line, severity)
                    for code, msg, at, severity in resolver.problems[before:]]
        if not any(n.kind == TASK_KIND for n in assembly.nodes.values()):  # else the tasks' check says it
            out += remap_problems([], assembly, DataflowSettings.of(context.settings).remap)
        return out

    def activate(self, host: Host) -> BridgeParticipant:
        """Runs the bridges: tasks added at start, inputs connected (remote ones by a connector)."""
        return BridgeParticipant(host)


def _remote_inputs(spec: BridgeSpec, assembly: AssemblyView, context: CheckContext,
                   specs: dict[str, tuple[BridgeSpec, Element]]) -> list[Problem]:
    """The inputs whose source is no task or bridge of the composite: a warning offline,
    an error online when no name service knows it (see :func:`remote_end`)."""
    out: list[Problem] = []
    for inp in spec.inputs:
        comp = inp.source[0]
        if inp.topic is not None or comp in assembly.nodes or comp in specs or inp.loc is None:
            continue
        loc = inp.loc

        def add(message: str, severity: Severity, _loc: Location = loc) -> None:
            out.append(Problem(BRIDGE, message, _loc.path, _loc.line, severity))

        remote_end(comp, f"bridge {spec.name!r} input {inp.name!r}", inp.ns, assembly, context, add)
    return out


def _fail(resolver: Resolver, spec: BridgeSpec) -> ScartError:
    why = "; ".join(p[1] for p in resolver.problems if p[3] == "error") or "it cannot be resolved"
    return ScartError(f"bridge {spec.name} ({spec.where}): {why}")


class BridgeParticipant(Participant):
    """Creates, connects, starts and stops the bridges of one runtime. A bridge whose
    source of another deployer is not in the name service yet waits for it, as
    ``scart:connect`` does: a watcher resolves it again every :data:`RETRY_S` s and starts
    it once every source is known (one of the wrong type is then logged, not retried)."""

    def __init__(self, host: Host) -> None:
        self.host = host
        self.tasks: list[BridgeTask] = []
        self._connectors: list[ConnectParticipant] = []
        self._pending: list[BridgeSpec] = []
        self._streams: list[str] = []  # the bridges' own ports joined to topics
        self._waiting: Watcher | None = None
        self._lock = threading.Lock()  # the watcher adds bridges while stop may run

    def start(self) -> None:
        """Resolve each bridge (remote sources through the name service now), add its task,
        connect its inputs and start it; one waiting for a remote source starts when it
        appears. Raises ``ScartError`` naming the bridge."""
        dataflow_host = host_of(self.host)
        specs = bridges_of(self.host.assembly.elements_of(BridgeElement.name))
        resolver = Resolver(self.host.assembly, self.host.settings, self.host.assembly.import_object, specs)
        remote: list[Link] = []
        for spec in specs.values():
            resolved = resolver.resolve(spec, online=True)
            if resolved is None:
                raise _fail(resolver, spec)
            if self._unknown(resolved):
                self._pending.append(spec)
                continue
            remote += self._add(resolved)
        dataflow_host.start()  # served (settings.serve) even when the bridges are the only data-flow parts
        dataflow_host.refresh()
        self._connect_remote(remote)
        if self._pending:
            self._waiting = Watcher("scart-bridge-wait", self._retry, interval=RETRY_S)
            self._waiting.start()

    def _unknown(self, resolved: Resolved) -> list[str]:
        """The inputs of a resolved bridge whose source type is not known yet (logged once)."""
        unknown = [n for n in resolved.sources if resolved.sources[n] is _UNKNOWN]
        if unknown and resolved.spec not in self._pending:
            sources = ", ".join(".".join(i.source) for i in resolved.spec.inputs if i.name in unknown)
            log.warning("bridge %s (%s): waiting for %s in the name service %s", resolved.spec.name,
                        resolved.spec.where, sources, host_of(self.host).ns_address)
        return unknown

    def _add(self, resolved: Resolved) -> list[Link]:
        """Add, configure, connect (in-process inputs) and start one bridge's task; its
        inputs from other deployers, to connect. Raises ``ScartError`` naming the bridge."""
        spec, remap = resolved.spec, DataflowSettings.of(self.host.settings).remap
        deployer = host_of(self.host).deployer
        task = BridgeTask(resolved, remap)
        deployer.add(task)
        with self._lock:
            self.tasks.append(task)
        if not task.configure():
            raise ScartError(f"bridge {spec.name}: configure refused (state {task.state.name})")
        names = set(deployer.names())
        remote: list[Link] = []
        for inp in spec.inputs:
            sink = (task.name, task._inputs[inp.name].port.name)
            if inp.topic is not None:
                self._stream(".".join(sink), inp.topic, inp.policy)
                continue
            source = remap.endpoint(*inp.source)
            if source[0] in names:
                deployer.connect(".".join(source), ".".join(sink), inp.policy)
            else:
                remote.append(Link(source, sink, inp.policy, inp.ns, inp.where))
        if spec.output_topic is not None:
            self._stream(f"{task.name}.{task.output.name}", spec.output_topic, ConnPolicy.data())
        connect_present(self.host, task.name)
        if not task.start():
            raise ScartError(f"bridge {spec.name}: start refused (state {task.state.name})")
        return remote

    def _stream(self, port: str, topic: TopicSpec, policy: ConnPolicy) -> None:
        """Join the bridge's ``port`` to ``topic`` (undone at stop). Raises ``ScartError``."""
        deployer = host_of(self.host).deployer
        try:
            made = deployer.stream(port, policy.with_(transport=topic.transport, topic=topic.topic),
                                   dict(topic.options))
        except (DataflowError, ValueError) as exc:
            raise ScartError(f"bridge stream {port} ({topic.loc}): {exc}") from exc
        with self._lock:
            self._streams.append(made.name)
        log.info("bridge stream %s: %s -> %s", made.name, made.source, made.sink)

    def _connect_remote(self, links: list[Link]) -> None:
        """Connect inputs from other deployers in the background (whenever their source appears)."""
        if not links:
            return
        with self._lock:
            local = {t.name for t in self.tasks}
            connector = ConnectParticipant(links, self.host, local=lambda name: name in local)
            self._connectors.append(connector)
        connector.start()

    def _retry(self) -> None:
        """Watcher step: resolve the waiting bridges again; start those now known."""
        specs = bridges_of(self.host.assembly.elements_of(BridgeElement.name))
        for spec in list(self._pending):
            resolver = Resolver(self.host.assembly, self.host.settings, self.host.assembly.import_object, specs)
            resolved = resolver.resolve(spec, online=True)
            if resolved is None:  # the source appeared, and does not fit: say so once, stop waiting
                log.error("%s", _fail(resolver, spec))
                self._pending.remove(spec)
                continue
            if self._unknown(resolved):
                continue
            self._pending.remove(spec)
            try:
                links = self._add(resolved)
            except (ScartError, DataflowError) as exc:  # the run goes on without this bridge
                log.error("bridge %s (%s): not started: %s", spec.name, spec.where, exc)
                continue
            host_of(self.host).refresh()
            self._connect_remote(links)
            log.info("bridge %s: its sources appeared: started", spec.name)

    def addresses(self) -> dict[str, str]:
        """What the runtime's data-flow host serves (the same as its tasks' participant says)."""
        return host_of(self.host).addresses()

    def stop(self) -> None:
        """Stop waiting, the connectors and every bridge task (idempotent)."""
        if self._waiting is not None:
            self._waiting.stop()
        with self._lock:
            connectors, self._connectors = list(self._connectors), []
            tasks = list(self.tasks)
            streams, self._streams = list(self._streams), []
        for connector in connectors:
            connector.stop()
        deployer = host_of(self.host).deployer
        for name in reversed(streams):
            deployer.unstream(name)
        for task in reversed(tasks):
            try:
                retire(task)
            except DataflowError as exc:
                log.warning("bridge %s: stopping: %s", task.name, exc)


#: How often (s) a bridge waiting for a source of another deployer looks for it again.
RETRY_S = 0.5


__all__ = ["BRIDGE", "BRIDGE_TYPE", "BridgeElement", "BridgeParticipant", "BridgeSpec", "BridgeTask", "InputSpec",
           "Resolved", "bridges_of", "parse_bridge", "path_type", "same_type"]
