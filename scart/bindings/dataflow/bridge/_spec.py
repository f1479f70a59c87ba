"""A ``<scart:bridge>`` as read: its inputs, output, trigger and topics (no type is
resolved here; :mod:`._resolve` does that)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from dataflow import ConnPolicy
from dataflow.fields import parse_path
from scart.bindings.dataflow._plan import MIN_PERIOD_S
from scart.spi import Element, Location

__all__ = ["BRIDGE", "BRIDGE_TYPE", "ELEMENT", "BridgeSpec", "InputSpec", "MAX_INPUTS", "MISSING", "TRIGGERS", "TopicSpec",
           "bridges_of", "parse_bridge"]

#: Problem codes of the bridge.
BRIDGE = "SCART-B001"  # a malformed bridge: attributes, inputs, output, trigger, a callable not found
BRIDGE_TYPE = "SCART-B002"  # types that do not agree: source, converter, builder, output

ELEMENT = "bridge"  #: the element's local name, ``<scart:bridge>``
TRIGGERS = ("periodic", "any", "all")
MISSING = ("hold", "skip", "default")
MAX_INPUTS = 64

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


def bridges_of(elements: list[tuple[str, Element]]) -> dict[str, BridgeSpec]:
    """The well-formed bridges among ``elements``, by name."""
    return {spec.name: spec for prefix, el in elements if (spec := parse_bridge(prefix, el)[0]) is not None}
