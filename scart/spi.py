"""The extension SPI: what a binding, an implementation kind or a composite element
provides, and what the runtime offers it. An extension imports from scart only this
module and the public error tree (:mod:`scart.errors`).

An extension is a *provider* registered under the local name of its XML element, found
through the ``scart.extensions`` entry points (see :mod:`scart.extensions`)::

    [project.entry-points."scart.extensions"]
    "binding.foo" = "foo_binding:FooBinding"       # a BindingProvider subclass

=========================  ==================================================================
provider                   provides
=========================  ==================================================================
:class:`BindingProvider`   ``check`` (static, before anything starts), ``service`` (a
                           :class:`ServiceBinding`: start, stop, its real address),
                           ``reference`` (a :class:`ReferenceBinding`: one invoker per
                           operation)
:class:`ImplementationProvider`  ``component_type`` (what the implementation declares, at
                           load time), ``check`` (static, of its assembled components) and
                           ``manager`` (a :class:`ComponentManager` creating, starting and
                           stopping its instances)
:class:`ElementProvider`   ``check`` of ``<scart:NAME>`` children of ``<composite>``
every provider             ``activate(host)``: a :class:`Participant` run with the composite
:class:`LaunchProvider`    what an extension adds to ``scart run``, ``validate`` and
                           ``graph``: its own settings (carried in ``Settings.extensions``),
                           its command-line options, the names its components run under,
                           its graph edges, and what it serves beside a running composite
                           (a :class:`Launched`); found through the ``scart.launch`` entry
                           points, every one installed takes part
=========================  ==================================================================

What the runtime offers, :class:`Host`: the :class:`~scart.settings.Settings`, the
assembly (:class:`AssemblyView`: to read, never to change), bounded work submission, service endpoints by name, shared
resources by key, and stop hooks. Lifecycle, in one table::

    runtime start()                            runtime stop() (reverse)
    1 reference bindings: start()              5 service bindings: stop()
    2 components: manager.start() (@init,      4 participants: stop()
      targets first)                           3 one-way pool drained
    3 participants: start() (after every       2 components: manager.stop() (@destroy)
      @init, before any service binding)       1 reference bindings: stop(), then stop hooks
    4 service bindings: start()

Static checks must not touch the network unless ``context.settings.online`` is set. A
check may return warnings (``Problem(..., severity="warning")``): the composite still
loads, and ``scart validate`` and ``scart run`` show them.
"""

from __future__ import annotations

import argparse
import re
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Literal, Protocol, TypeAlias, TypeVar

from pydantic import BaseModel

from scart.api import CURRENT_CALLBACK, ComponentType, InterfaceInfo, Operation, PropSpec
from scart.errors import Problem
from scart.graph import DEFAULT, Bound, Node, Target
from scart.model import SCART_NS, Binding, Element, Implementation, Location
from scart.scdl import did_you_mean, parse_xml
from scart.settings import Settings

__all__ = [
    "CURRENT_CALLBACK", "DEFAULT", "SCART_NS", "AssemblyView", "Binding", "BindingProvider", "Bound",
    "CheckContext", "ComponentManager", "ComponentType", "Element", "ElementProvider", "Extension", "GraphEdge",
    "GraphNode", "Host", "Implementation", "ImplementationProblem", "ImplementationProvider", "InterfaceInfo",
    "Invocation", "Invoker", "LaunchContext", "LaunchProvider", "Launched", "Location", "Node", "Operation", "Participant",
    "Problem", "PropSpec", "ReferenceBinding", "ServiceBinding", "ServiceEndpoint", "Settings", "Side", "Target",
    "Verb", "did_you_mean", "parse_host_port", "parse_xml", "port_in_range",
]

T = TypeVar("T")
Side = Literal["service", "reference"]
#: A callable that performs one operation of a service: arguments in, the operation's
#: result out. Operations return whatever their interface says, so the result is Any.
Invoker: TypeAlias = "Callable[..., Any]"


# --- what the runtime offers -------------------------------------------------------------


@dataclass(frozen=True)
class Invocation:
    """One call: operation name, arguments, and the callback target (or None)."""

    operation: str
    args: tuple[object, ...] = ()
    kwargs: dict[str, object] = field(default_factory=dict)
    callback: object | None = None


class ServiceEndpoint(Protocol):
    """A component service as bindings see it (implemented by the runtime)."""

    component: str
    service: str
    interface: InterfaceInfo

    def method(self, operation: str) -> Invoker:
        """The raw callable for ``operation`` on the right instance (scope handled); no
        callback, one-way or pass-by-value handling. Raises ``KeyError`` if unknown."""

    def operation(self, name: str, callback: object | None) -> Invoker:
        """The full callable for ``name`` (callback routed, one-way queued, by-value copied)."""

    def invoke(self, invocation: Invocation) -> Any:
        """Perform ``invocation``; returns the result (None at once for one-way)."""


class AssemblyView(Protocol):
    """The checked composite, to read (typed as read-only mappings; extensions never change
    it): leaf components by path, promoted services, and the extension elements of every
    composite level as ``(path prefix, element)``."""

    @property
    def nodes(self) -> Mapping[str, Node]: ...

    @property
    def services(self) -> Mapping[str, Target]: ...

    @property
    def service_bindings(self) -> Mapping[str, Sequence[Binding]]: ...

    @property
    def elements(self) -> Sequence[tuple[str, Element]]: ...

    def elements_of(self, kind: str) -> list[tuple[str, Element]]: ...

    def import_object(self, ref: str) -> object:
        """Import ``"pkg.mod:Attr"`` from the contributions, as the checks did (raises what importing raises)."""


class Host(Protocol):
    """What the runtime offers extensions. Every method is thread-safe."""

    @property
    def settings(self) -> Settings:
        """The runtime's settings (name service, timeouts...)."""

    @property
    def assembly(self) -> AssemblyView:
        """The composite this runtime runs."""

    @property
    def drain_timeout(self) -> float:
        """How long (s) stopping waits for work in flight before leaving it behind."""

    def submit(self, fn: Callable[..., object], *args: object, **kwargs: object) -> None:
        """Run ``fn(*args, **kwargs)`` on the runtime's bounded one-way pool; failures are
        logged and counted; raises ``ScartError`` when the pool is full (backpressure)."""

    def submitter(self, label: str) -> Callable[..., None]:
        """A :meth:`submit` whose calls are named ``label`` in logs."""

    def endpoint(self, name: str) -> ServiceEndpoint:
        """The endpoint of a local service ("Component/Service"); raises ``ServiceNotFoundError``."""

    def shared(self, key: str, factory: Callable[[], T]) -> T:
        """A per-runtime resource, created by ``factory`` on first use (once, even when
        called from several threads). Keys are namespaced by convention: ``"scart.bindings.grpc.servers"``."""

    def add_stop_hook(self, hook: Callable[[], None]) -> None:
        """Run ``hook`` at the very end of stop (after every @destroy), hooks in reverse order."""

    def configure(self, node: Node, instance: object) -> None:
        """Inject properties, references and context into a fresh ``instance`` of ``node``."""


@dataclass(frozen=True)
class CheckContext:
    """What a static check may look at: the contribution (its folder and root composite)
    and the settings. ``import_object("pkg.mod:Class")`` imports from the contribution."""

    folder: Path
    root_file: str
    settings: Settings
    importer: Callable[[str], object] = field(repr=False)

    def import_object(self, ref: str) -> object:
        """Import ``"pkg.mod:Attr"`` with the contribution folder first on ``sys.path``;
        raises what importing raises (``ImportError``, ``AttributeError``, ``ValueError``)."""
        return self.importer(ref)


# --- what extensions run -----------------------------------------------------------------


class Participant(ABC):
    """Something an extension runs with the composite (see the lifecycle table)."""

    @abstractmethod
    def start(self) -> None:
        """Start: every component is initialised; no service binding is started yet."""

    @abstractmethod
    def stop(self) -> None:
        """Stop: service bindings are stopped; no component is destroyed yet. Idempotent."""

    def addresses(self) -> dict[str, str]:
        """What it serves, once started: ``{"what": "where"}`` (``scart run`` prints them)."""
        return {}


class ServiceBinding(ABC):
    """Service side of a binding: exports ``endpoint`` until stopped."""

    def __init__(self, model: Binding, endpoint: ServiceEndpoint, host: Host) -> None:
        self.model = model
        self.endpoint = endpoint
        self.host = host

    @abstractmethod
    def start(self) -> None:
        """Start accepting calls. Called once, after every component is initialised."""

    @abstractmethod
    def stop(self) -> None:
        """Stop accepting calls and release resources; idempotent; blocks until done."""

    @property
    def address(self) -> str | None:
        """The real address once started (None for bindings without one)."""
        return None


class ReferenceBinding(ABC):
    """Reference side of a binding: one callable per operation of ``interface``."""

    def __init__(self, model: Binding | None, interface: InterfaceInfo, host: Host) -> None:
        self.model = model
        self.interface = interface
        self.host = host

    @abstractmethod
    def invoker(self, operation: Operation, callback: object | None) -> Invoker:
        """A callable performing ``operation``; built once, called many times, thread-safe.
        ``callback`` is the caller's callback target (one attribute per callback operation) or None."""

    def start(self) -> None:
        """Open connections if needed (default: nothing). Called before components' @init."""

    def stop(self) -> None:
        """Close connections (default: nothing); idempotent."""


class ComponentManager(ABC):
    """Owns the instances of one component. ``start``/``stop`` are called once each.

    ``stage`` says what ``start`` is doing (e.g. ``"@init open"``, ``"start_hook"``), so a
    start that does not return can be named (``scart run --start-timeout``)."""

    def __init__(self, node: Node, host: Host) -> None:
        self.node = node
        self.host = host
        self.stage = "start"

    @abstractmethod
    def method(self, operation: str) -> Invoker:
        """The raw callable running ``operation`` on the right instance."""

    @abstractmethod
    def start(self) -> None:
        """Create eager instances and run their @init."""

    @abstractmethod
    def stop(self) -> None:
        """Run @destroy of live instances; idempotent."""

    def instance(self) -> object | None:
        """The current instance (composite scope), or None."""
        return None


class ImplementationProblem(Exception):
    """Raised by ``component_type``: the implementation cannot be used (``code``, message).

    ``partial`` may carry enough of a component type for the assembler to check the rest
    of the component (its properties, references) despite the problem."""

    def __init__(self, code: str, message: str, partial: ComponentType | None = None) -> None:
        super().__init__(message)
        self.code = code
        self.partial = partial


# --- providers ---------------------------------------------------------------------------


class Extension(ABC):
    """Base of every provider; ``name`` is the local name of its XML element."""

    name: ClassVar[str] = ""

    def activate(self, host: Host) -> Participant | None:
        """Once per runtime whose composite uses this extension, at start: what to run with
        the composite (default: nothing). Several providers may return the same object
        (for example one shared through ``host.shared``); it is started once."""
        return None


class BindingProvider(Extension):
    """A binding kind (``binding.NAME`` on a service and/or a reference)."""

    sides: ClassVar[frozenset[str]] = frozenset({"service", "reference"})

    def check(self, model: Binding, interface: InterfaceInfo | None, side: Side,
              context: CheckContext) -> list[Problem]:
        """Static problems of this binding element (default none)."""
        return []

    def names_endpoint(self, model: Binding) -> bool:
        """Does this binding, on a reference, name the endpoint it reaches (so a ``@target``
        beside it would be a second, conflicting one: ASM50026)? Default: it has a ``@uri``."""
        return "uri" in model.attributes

    def service(self, model: Binding, endpoint: ServiceEndpoint, host: Host) -> ServiceBinding:
        """The service side for ``endpoint`` (called only when ``"service" in sides``)."""
        raise NotImplementedError(f"{self.name} has no service side")

    def reference(self, model: Binding, interface: InterfaceInfo, host: Host) -> ReferenceBinding:
        """The reference side for ``interface`` (called only when ``"reference" in sides``)."""
        raise NotImplementedError(f"{self.name} has no reference side")


class ImplementationProvider(Extension):
    """An implementation kind (``implementation.NAME`` in a component)."""

    @abstractmethod
    def component_type(self, impl: Implementation, context: CheckContext) -> ComponentType:
        """What the implementation declares; raises :class:`ImplementationProblem`."""

    @abstractmethod
    def manager(self, node: Node, host: Host) -> ComponentManager:
        """A manager for the component ``node``."""

    def check(self, nodes: list[Node], assembly: AssemblyView, context: CheckContext) -> list[Problem]:
        """Static problems of the components of this kind, once the composite is assembled
        (their property values parsed; ``node.property_locations`` says where each was
        given): what starting them would refuse and needs no running peer. Default none."""
        return []


class ElementProvider(Extension):
    """A composite-level extension element (``<scart:NAME>`` child of ``<composite>``),
    read generically into the assembly's ``elements`` (declare it in the shipped XSD)."""

    def check(self, elements: list[tuple[str, Element]], assembly: AssemblyView,
              context: CheckContext) -> list[Problem]:
        """Static problems of every such element (``(path prefix, element)`` pairs)."""
        return []


# --- launching a composite (scart run, validate, graph) -----------------------------------

#: The composite verbs a :class:`LaunchProvider` takes part in.
Verb = Literal["run", "validate", "graph"]


@dataclass(frozen=True)
class GraphNode:
    """A node an extension adds to ``scart graph``: a Graphviz ``shape`` ("" keeps the
    box) and ``label``, or an ``xlabel`` beside it; several with one ``id`` merge, as in DOT."""

    id: str
    label: str = ""
    shape: str = ""
    xlabel: str = ""


@dataclass(frozen=True)
class GraphEdge:
    """An edge an extension adds to ``scart graph``, between node ids (component paths,
    or its own :class:`GraphNode` s)."""

    source: str
    target: str
    label: str = ""
    style: Literal["", "dashed", "dotted", "bold"] = ""
    color: str = ""


@dataclass(frozen=True)
class LaunchContext:
    """What a launch provider is told once the composite runs (``scart run``): the
    settings, what the runtime's participants serve (``{"what": "where"}``), and where
    the component services are served (None: not served, ``--services off``)."""

    settings: Settings
    served: Mapping[str, str]
    services_address: str | None


class Launched(Participant):
    """What a :class:`LaunchProvider` serves beside a running composite (``scart run``):
    started after the composite and its services endpoint (``start`` raises, naming its
    option, when it cannot: the run then stops), stopped before them. Once everything
    started, ``scart run`` says each of :meth:`addresses` (``what at where``) and
    :meth:`notes`."""

    def notes(self) -> list[str]:
        """Lines to say once started (default none)."""
        return []

    def services_option(self) -> str | None:
        """The options by which ``scart services`` and ``scart call`` find the services
        endpoint by name through this (``" --ns HOST:PORT"``; ``""``: their defaults do),
        or None when it does not list them (default)."""
        return None

    def service_name(self, name: str) -> str:
        """The name ``scart call`` finds the service ``name`` by through this (a namespace
        put before it, ``--remap __ns=``); default ``name``."""
        return name


class LaunchProvider(ABC):
    """What an extension adds to launching a composite (``scart run``, ``validate`` and
    ``graph``), as Tuscany's module activators do: its own settings (a frozen pydantic
    model, carried in ``Settings.extensions``), its command-line options, the names its
    components run under, its graph edges, and what it serves beside a running composite.

    Registered under ``name`` in the ``scart.launch`` entry points; every one installed
    takes part. Loaded when a composite verb builds its options, or when a runtime reads
    its settings from the environment: its module imports nothing heavy."""

    name: ClassVar[str] = ""

    def add_arguments(self, parser: argparse.ArgumentParser, verb: Verb) -> None:
        """Add this extension's options to ``verb``'s parser (default none)."""

    def settings(self, args: argparse.Namespace, verb: Verb, environ: Mapping[str, str]) -> BaseModel | None:
        """This extension's settings from ``verb``'s options (the environment where an
        option is absent); None: none of its own (default). Raises ``ValueError`` naming
        the option or variable for a bad value."""
        return None

    def from_env(self, environ: Mapping[str, str]) -> BaseModel | None:
        """This extension's settings from the environment alone (a runtime made without
        settings); None: none of its own (default). Raises ``ValueError`` naming the variable."""
        return None

    def names(self, assembly: AssemblyView, settings: Settings) -> Mapping[str, str]:
        """The name the components of this extension run under, by component path (``scart
        run`` and ``scart graph`` show it). Default: none renamed."""
        return {}

    def graph(self, assembly: AssemblyView, settings: Settings) -> Sequence[GraphNode | GraphEdge]:
        """What this extension adds to ``scart graph`` (default nothing)."""
        return ()

    def launch(self, context: LaunchContext) -> Launched | None:
        """What to serve beside the running composite (``scart run``), not started yet;
        None: nothing (default)."""
        return None


# --- helpers for extension authors -------------------------------------------------------

#: The callback target of the call being executed: a service binding sets it (``set`` /
#: ``reset``) around a call it runs, so that the provider's ``scart.callback()`` yields the
#: caller's callback proxy (see :func:`scart.local.wrap_operation`).
CURRENT_CALLBACK = CURRENT_CALLBACK

#: The namespace of scart's own XML elements, ``urn:scart:1.0``.
SCART_NS = SCART_NS

#: ``parse_xml(path, problems)``: parse an XML file of the contribution safely (size bound,
#: no DTD, no entities, no network); problems are appended, None returned on failure.
parse_xml = parse_xml

#: ``did_you_mean(word, known)``: " (did you mean 'x'?)" when ``word`` looks like a
#: misspelling of one of ``known``, else "" (for messages naming what a composite names).
did_you_mean = did_you_mean

_HOST_PORT = re.compile(r"^(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(?P<port>[0-9]{1,5})$")


def parse_host_port(text: str) -> tuple[str, int] | None:
    """``(host, port)`` of a "host:port" address (host a name, IPv4 or bracketed IPv6),
    or None when ``text`` is not of that shape. The port is not range-checked: see
    :func:`port_in_range`."""
    m = _HOST_PORT.match(text)
    return None if m is None else (m["host"], int(m["port"]))


def port_in_range(port: int, *, zero_ok: bool = False) -> bool:
    """Whether ``port`` is 1..65535 (0..65535 with ``zero_ok``: "any free port")."""
    return (0 if zero_ok else 1) <= port <= 65535
