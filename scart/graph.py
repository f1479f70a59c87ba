"""The resolved component graph the runtime runs: plain data, no XML and no threads.

:func:`scart.assembly.assemble` builds an :class:`Assembly` from a composite and checks
it; the runtime turns it into running components. Leaf components are :class:`Node` s
named by their path ("Outer/Inner"); a reference resolves to endpoints: a
:class:`Target` in this runtime or a :class:`Bound` binding element.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from scart.api import ComponentType, InterfaceInfo
from scart.errors import Problem
from scart.model import Binding, Component, Composite, Element, Location

if TYPE_CHECKING:
    from scart.contribution import Contribution
    from scart.extensions import ExtensionRegistry

__all__ = ["DEFAULT", "Assembly", "Bound", "Endpoint", "Node", "Target"]


@dataclass(frozen=True)
class Target:
    """A reference endpoint in this runtime: leaf component path and service name."""

    node: str
    service: str


@dataclass(frozen=True)
class Bound:
    """A reference endpoint reached through a binding (no local target)."""

    binding: Binding


Endpoint = Target | Bound


@dataclass
class Node:
    """A leaf component: implementation kind and type, values to inject, resolved references."""

    path: str
    model: Component
    kind: str
    ctype: ComponentType
    properties: dict[str, Any] = field(default_factory=dict)
    references: dict[str, list[Endpoint]] = field(default_factory=dict)
    service_bindings: dict[str, list[Binding]] = field(default_factory=dict)
    # service -> the paths it is promoted as out of nested composites whose bindings it carries
    service_aliases: dict[str, list[str]] = field(default_factory=dict)
    ref_interfaces: dict[str, InterfaceInfo] = field(default_factory=dict)  # as declared in the composite
    # property -> where its value was given: its <property>, "<command line>" (--set), else the component
    property_locations: dict[str, Location] = field(default_factory=dict)


@dataclass
class Assembly:
    """The checked, resolved graph: leaf ``nodes`` by path, ``order`` (targets first),
    top-level promoted ``services`` and their ``service_bindings``, the extension
    ``elements`` of every composite level, and the ``registry`` it was checked against."""

    composite: Composite
    contribution: Contribution
    registry: ExtensionRegistry
    nodes: dict[str, Node]
    order: list[str]
    services: dict[str, Target]
    service_bindings: dict[str, list[Binding]]
    aliases: dict[str, Target] = field(default_factory=dict)  # "Comp", "Comp/Service" of top-level components
    elements: list[tuple[str, Element]] = field(default_factory=list)  # (prefix, <scart:...>) of all composites
    unused_overrides: set[str] = field(default_factory=set)  # overrides naming no property (non-strict mode)
    warnings: list[Problem] = field(default_factory=list)  # what loads but looks wrong (``scart validate`` shows it)

    def elements_of(self, kind: str) -> list[tuple[str, Element]]:
        """The ``(prefix, element)`` pairs of extension elements whose local name is ``kind``."""
        return [(prefix, el) for prefix, el in self.elements if el.kind == kind]

    def import_object(self, ref: str) -> object:
        """Import ``"pkg.mod:Attr"`` from the contributions, as the checks did."""
        return self.contribution.import_object(ref)


class _DefaultType:
    def __repr__(self) -> str:
        return "<default>"


#: The value of a property left to its declared default (the manager supplies it).
DEFAULT: Any = _DefaultType()
